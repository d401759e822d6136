# Python needs only the C side of rosidl: the C structs, the C type supports (Fast DDS and introspection; the Fast DDS
# RMW loads both) and the Python bindings. The C++ generators (structs and two C++ type supports) register themselves
# too, whenever a dependency such as geometry_msgs is found; nothing in Python loads what they build, and they take
# about half of the build. Call this right before rosidl_generate_interfaces() to leave only the C and Python
# generators registered, and tb4_unity_build_exclusions() right after it.
#
# The generated sources are compiled as unity builds (each target's files included into a few translation units)
# at -O1: one Fast DDS type support file is ~1.9 CPU-s at -O3, almost all of it parsing the same Fast CDR and C++
# headers again, and nav2_msgs has 51 of them; unity at -O1 compiles all 51 in ~15 CPU-s. The code is thin glue
# (init/fini, copy, CDR and Python conversion calling the wheels' own -O2 libraries for nested standard types).
macro(tb4_python_only_generators)
  set(_tb4_generators "")
  foreach(_extension IN LISTS AMENT_EXTENSIONS_rosidl_generate_idl_interfaces)
    string(REGEX MATCH "^[a-z_]+_cpp:" _is_cpp "${_extension}")
    if(NOT _is_cpp)
      list(APPEND _tb4_generators "${_extension}")
    endif()
  endforeach()
  set(AMENT_EXTENSIONS_rosidl_generate_idl_interfaces ${_tb4_generators})
  set(CMAKE_UNITY_BUILD ON)
  set(CMAKE_UNITY_BUILD_BATCH_SIZE 16)
  set(CMAKE_C_FLAGS_RELEASE "-O1 -DNDEBUG")
  set(CMAKE_CXX_FLAGS_RELEASE "-O1 -DNDEBUG")
endmacro()

# Each <interface>__description.c defines the same file-level statics (implicit_encoding and others), so two of them
# cannot share a translation unit: they are compiled one by one.
function(tb4_unity_build_exclusions)
  get_target_property(_sources ${PROJECT_NAME}__rosidl_generator_c SOURCES)
  foreach(_source IN LISTS _sources)
    if(_source MATCHES "__description\\.c$")
      set_source_files_properties(${_source} PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
    endif()
  endforeach()
endfunction()
