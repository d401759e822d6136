"""TurtleBot 4 Navigator: script and test TurtleBot 4 missions, with a built-in simulator.

Importing `tb4` never imports rclpy; the ROS parts load on first use (see `tb4.rosenv`).
"""

from tb4.rosenv import apply_safe_ros_defaults

__version__ = "0.1.0"
__all__ = ["__version__", "apply_safe_ros_defaults"]

apply_safe_ros_defaults()
