"""The ROS-free foundation every other package builds on: one home each for geometry and units (geometry, units,
directions), the occupancy map type both the simulator and the navigation core read (maps), the robot's
parameters (robot_params) and bounded waiting (waits). Plain Python + NumPy; never imports rclpy.
"""
