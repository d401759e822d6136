"""`ground_truth`: the simulator's true pose as nav_msgs/Odometry in the map frame, for measuring localization.

A real robot has no such topic; a simulator offers it (as Gazebo's p3d plugin does) so users can plot the AMCL
estimate against the truth. Published at the odometry rate with the true body velocities; a robot standing still
repeats the same pose, which goes out at most 50 times a wall second (tb4.ros.robot.common.Throttle).
"""

from __future__ import annotations

import struct
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node

from tb4.ros.convert import StampedSerialization, set_yaw
from tb4.ros.loop import LoopView
from tb4.ros.robot.common import Throttle

__all__ = ["GroundTruthPublisher", "GROUND_TRUTH_PERIOD"]

GROUND_TRUTH_PERIOD = 0.05  # s of sim time (20 Hz, like odom)


class GroundTruthPublisher:
    def __init__(self, node: Node, loop: LoopView, base_frame: str = "base_link") -> None:
        self.loop = loop
        self.base_frame = base_frame
        self.pub = node.create_publisher(Odometry, "ground_truth", 10)
        msg = Odometry()
        msg.header.frame_id = "map"
        msg.child_frame_id = base_frame
        self._serialized = StampedSerialization(msg)  # a robot standing still: only the stamp changes
        self._throttle = Throttle()
        loop.every(GROUND_TRUTH_PERIOD, self.publish)

    def publish(self, now: float) -> None:
        if self.pub.get_subscription_count() == 0:
            return
        pose = self.loop.sim.pose()
        v, w = self.loop.sim.velocity()
        values = (float(pose.x), float(pose.y), float(pose.yaw), float(v), float(w))
        key = struct.pack("5d", *values)
        if self._throttle.repeat_too_soon("ground_truth", self._serialized.repeats(key)):
            return

        def fill(msg: Any) -> None:
            x, y, yaw, v, w = values
            msg.pose.pose.position.x = x
            msg.pose.pose.position.y = y
            set_yaw(msg.pose.pose.orientation, yaw)
            msg.twist.twist.linear.x = v
            msg.twist.twist.angular.z = w

        self.pub.publish(self._serialized.serialized(now, key, fill))
