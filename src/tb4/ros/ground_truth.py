"""`ground_truth`: the simulator's true pose as nav_msgs/Odometry in the map frame, for measuring localization.

A real robot has no such topic; a simulator offers it (as Gazebo's p3d plugin does) so users can plot the AMCL
estimate against the truth. Published at the odometry rate (20 Hz of sim time) with the true body velocities, and
bounded per wall second as odom is (tb4.ros.robot.common: at most 250, a still robot's repeats at most 50): at
--rate max a drive sent 700 a wall second, a tenth of the simulator loop's time, read by one watcher. Whatever that
bound drops, the truth at the stamp of every amcl_pose always goes out (`beside_estimate`), so an estimate can
always be paired with the truth of its own moment.
"""

from __future__ import annotations

import struct
import threading
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node

from tb4.ros.convert import StampedSerialization, set_yaw
from tb4.ros.loop import LoopView
from tb4.ros.robot.common import MIN_WALL_PERIOD, Throttle

__all__ = ["GroundTruthPublisher", "GROUND_TRUTH_PERIOD", "GROUND_TRUTH_DEPTH"]

GROUND_TRUTH_PERIOD = 0.05  # s of sim time (20 Hz, like odom)
# The writer keeps a wall second of samples at the bound: a reliable reader that falls behind (a loaded machine)
# still gets every truth beside an estimate. With 10, as odom, a keep-last writer dropped the truth of 327.4 s
# before a watcher 10 samples behind had it (stress run s34), and that estimate had no truth.
GROUND_TRUTH_DEPTH = round(1.0 / MIN_WALL_PERIOD)


class GroundTruthPublisher:
    def __init__(self, node: Node, loop: LoopView, base_frame: str = "base_link") -> None:
        self.loop = loop
        self.base_frame = base_frame
        self.pub = node.create_publisher(Odometry, "ground_truth", GROUND_TRUTH_DEPTH)
        msg = Odometry()
        msg.header.frame_id = "map"
        msg.child_frame_id = base_frame
        self._serialized = StampedSerialization(msg)  # a robot standing still: only the stamp changes
        self._throttle = Throttle()
        self._lock = threading.Lock()  # the loop thread's samples and a ROS thread's (an initial pose's estimate)
        self._last_stamp = -1.0
        loop.every(GROUND_TRUTH_PERIOD, self.publish)
        loop.on_reset(self._on_reset)

    def _on_reset(self) -> None:
        """A world reset: stamps start from 0 again."""
        self._last_stamp = -1.0

    def publish(self, now: float) -> None:
        """The periodic sample (loop thread): within the wall-rate bounds."""
        self._publish(now, forced=False)

    def beside_estimate(self, now: float) -> None:
        """The truth at the stamp of an amcl_pose just sent (any thread), whatever the wall-rate bounds."""
        self._publish(now, forced=True)

    def _publish(self, now: float, forced: bool) -> None:
        if self.pub.get_subscription_count() == 0:
            return
        with self._lock:
            if now == self._last_stamp:  # already out at this stamp (the sample and an estimate share a tick)
                return
            with self.loop.lock:
                pose = self.loop.sim.pose()
                v, w = self.loop.sim.velocity()
            values = (float(pose.x), float(pose.y), float(pose.yaw), float(v), float(w))
            key = struct.pack("5d", *values)
            repeat = self._serialized.repeats(key)
            if not forced and (
                self._throttle.repeat_too_soon("ground_truth", repeat)
                or (not repeat and self._throttle.too_soon("ground_truth moving", MIN_WALL_PERIOD))
            ):
                return

            def fill(msg: Any) -> None:
                x, y, yaw, v, w = values
                msg.pose.pose.position.x = x
                msg.pose.pose.position.y = y
                set_yaw(msg.pose.pose.orientation, yaw)
                msg.twist.twist.linear.x = v
                msg.twist.twist.angular.z = w

            self._last_stamp = now
            self.pub.publish(self._serialized.serialized(now, key, fill))
