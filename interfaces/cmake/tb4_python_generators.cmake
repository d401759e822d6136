# Python needs only the C side of rosidl: the C structs, the C type supports (Fast DDS and introspection) and the
# Python bindings. The C++ generators (structs and two C++ type supports) register themselves too, whenever a
# dependency such as geometry_msgs is found; nothing in Python loads what they build, and they take about half of the
# build. Call this right before rosidl_generate_interfaces() to leave only the C and Python generators registered.
macro(tb4_python_only_generators)
  set(_tb4_generators "")
  foreach(_extension IN LISTS AMENT_EXTENSIONS_rosidl_generate_idl_interfaces)
    string(REGEX MATCH "^[a-z_]+_cpp:" _is_cpp "${_extension}")
    if(NOT _is_cpp)
      list(APPEND _tb4_generators "${_extension}")
    endif()
  endforeach()
  set(AMENT_EXTENSIONS_rosidl_generate_idl_interfaces ${_tb4_generators})
endmacro()
