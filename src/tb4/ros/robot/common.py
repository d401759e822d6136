"""What every part of the simulated Create 3's ROS side shares: rates, frames, QoS and the wall-rate throttle."""

from __future__ import annotations

import math
import time
from typing import Any

from geometry_msgs.msg import TransformStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tb4.ros.convert import time_msg, yaw_to_quaternion
from tb4.ros.qos import LATCHED

__all__ = ["RATES", "FRAMES", "RELIABLE", "LATCHED", "MIN_WALL_PERIOD", "SENSOR_WALL_PERIOD", "Throttle", "transform"]

#: Publication periods in sim seconds. The Create 3 sends its fast sensors at 62.5-100 Hz; the simulator steps its
#: control loop at 20 Hz (sim time), so those go out once per control tick.
RATES = {
    "clock": 0.02,
    "odom": 0.05,
    "scan": 0.1,
    "battery_state": 1.0,
    "dock_status": 0.2,
    "fast": 0.05,  # hazard_detection, ir_intensity, cliff_intensity, imu, mouse, wheel_vels, wheel_ticks, ir_opcode
    "status": 1.0,  # kidnap_status, slip_status, stop_status, wheel_status
}
MIN_WALL_PERIOD = 0.004  # s: clock, odom/tf and scan go out at most 250 times per wall second each
SENSOR_WALL_PERIOD = 0.02  # s: each other Create 3 sensor at most 50 times per wall second (changes still go out)
FRAMES = {"map": "map", "odom": "odom", "base": "base_link", "laser": "rplidar_link"}

#: Every topic is published reliably: rclpy's default subscription (reliable, volatile, depth 10) receives it, and
#: so does a sensor-data (best effort) one. The real Create 3 publishes its sensors best effort (see the README).
RELIABLE = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)


class Throttle:
    """At high speed-ups a topic would go out thousands of times per wall second, more than any subscriber can
    use: bound each topic's wall rate."""

    def __init__(self) -> None:
        self._last: dict[str, float] = {}

    def too_soon(self, topic: str, period: float = MIN_WALL_PERIOD) -> bool:
        wall = time.monotonic()
        if wall - self._last.get(topic, -math.inf) < period:
            return True
        self._last[topic] = wall
        return False

    def repeat_too_soon(self, topic: str, repeat: bool, period: float = SENSOR_WALL_PERIOD) -> bool:
        """For a message that may say again what the last one said (a robot charging on its dock for hours: its
        true pose, dock status and estimate): a change goes out at once, a repeat at most every `period` wall
        seconds. At --rate max such repeats were a quarter of the simulator's time while docked."""
        if repeat:
            return self.too_soon(topic, period)
        self._last[topic] = time.monotonic()
        return False


def transform(parent: str, child: str, x: float, y: float, yaw: float, stamp: float, z: float = 0.0) -> Any:
    t = TransformStamped()
    t.header.frame_id = parent
    t.header.stamp = time_msg(stamp)
    t.child_frame_id = child
    t.transform.translation.x = float(x)
    t.transform.translation.y = float(y)
    t.transform.translation.z = float(z)
    t.transform.rotation = yaw_to_quaternion(yaw)
    return t
