"""The simulated TurtleBot 4's ROS surface, one module per job; tb4.ros.create3_interfaces puts them together."""
