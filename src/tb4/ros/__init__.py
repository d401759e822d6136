"""The thin ROS 2 layer: the simulator process and its Create 3 / Nav2 interfaces. Importing it needs rclpy."""

from tb4.rosenv import require_ros

require_ros()
