"""The robot's basic topics: clock, odom, tf, tf_static, scan, battery_state, dock_status, and cmd_vel in.

cmd_vel takes geometry_msgs/Twist, like the Create 3; DDS allows one type per topic and participant, so a
TwistStamped publisher (e.g. Nav2 with enable_stamped_cmd_vel) uses cmd_vel_stamped. All published reliably
(odom too), so rclpy's default subscription receives them.

Building and sending a message costs the loop time at every tick, so a topic nobody subscribes to is skipped
(they are all volatile: a late subscriber gets the next one, as from a real robot), and each publisher fills one
message it keeps instead of building a new one (publish() serializes it at once). tf_static is latched
(transient local) and goes out once, whoever listens.
"""

from __future__ import annotations

import array
import math
import time

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from irobot_create_msgs.msg import DockStatus
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, LaserScan
from tf2_msgs.msg import TFMessage

from tb4.ros.convert import StampedSerialization, set_time, set_yaw
from tb4.ros.loop import LoopView
from tb4.ros.robot.common import LATCHED, RATES, RELIABLE, Throttle, transform
from tb4.ros.run_record import RobotRecord

__all__ = ["RobotTopics", "LASER_OFFSET"]

LASER_OFFSET = (0.0, 0.0, 0.2)  # RPLIDAR above the base centre; 2D ranges are from the robot centre


class RobotTopics:
    """Publishes the robot's state from the loop thread and turns cmd_vel into loop requests."""

    def __init__(
        self,
        node: Node,
        loop: LoopView,
        frames: dict[str, str],
        throttle: Throttle,
        clock: bool = True,
        record: RobotRecord | None = None,
    ) -> None:
        self.node = node
        self.record = record  # each bump goes into the run record, where the picture and a trial's checks find it
        self.loop = loop
        self.sim = loop.sim
        self.frames = frames
        self._throttle = throttle
        self.warnings = 0
        self.bumps = 0
        self._last_warning: dict[str, float] = {}
        loop.on_reset(self._on_reset)
        # one /clock per process: in a fleet only the first robot publishes it
        self.clock_pub = node.create_publisher(Clock, "/clock", RELIABLE) if clock else None
        self.odom_pub = node.create_publisher(Odometry, "odom", RELIABLE)
        self.tf_pub = node.create_publisher(TFMessage, "tf", 100)
        self.tf_static_pub = node.create_publisher(TFMessage, "tf_static", LATCHED)
        self.scan_pub = node.create_publisher(LaserScan, "scan", RELIABLE)
        self.battery_pub = node.create_publisher(BatteryState, "battery_state", RELIABLE)
        self.dock_pub = node.create_publisher(DockStatus, "dock_status", RELIABLE)
        node.create_subscription(Twist, "cmd_vel", self._on_twist, 10)
        node.create_subscription(TwistStamped, "cmd_vel_stamped", self._on_twist_stamped, 10)

        self._clock = Clock()
        self._odom = Odometry()
        self._odom.header.frame_id = frames["odom"]
        self._odom.child_frame_id = frames["base"]
        self._scan = LaserScan()
        self._scan.header.frame_id = frames["laser"]
        self._scan.scan_time = RATES["scan"]
        self._battery = BatteryState()
        self._battery.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_GOOD
        self._battery.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LION
        self._battery.present = True
        self._dock_status = StampedSerialization(DockStatus())  # the same two flags for hours on the dock
        self._publish_static(0.0)
        if clock:
            loop.every(RATES["clock"], self._publish_clock)
        loop.every(RATES["odom"], self._publish_odom)
        loop.every(RATES["scan"], self._publish_scan)
        loop.every(RATES["battery_state"], self._publish_battery)
        loop.every(RATES["dock_status"], self._publish_dock_status)
        loop.on_tick(self._report_hazards)

    def _on_reset(self) -> None:
        """A world reset: the new run has bumped nothing, and its warnings are its own (sim time starts at 0)."""
        self.bumps = 0
        self._last_warning.clear()

    def warn_limited(self, key: str, message: str, period: float = 1.0) -> None:
        """At most one warning per `period` wall seconds per key (a flood of bad input must not flood the log)."""
        now = time.monotonic()
        if now - self._last_warning.get(key, -math.inf) >= period:
            self._last_warning[key] = now
            self.node.get_logger().warn(message)

    def now(self) -> float:
        return self.sim.time

    # --- commands -------------------------------------------------------------------------------------------
    def _apply_velocity(self, v: float, w: float) -> None:
        if not (isinstance(v, float) and isinstance(w, float)):
            return
        try:
            ok, reason = self.loop.inputs.sim.set_velocity_command(v, w)
        except Exception as exc:
            ok, reason = False, str(exc)
        if not ok:
            self.warnings += 1
            self.warn_limited("cmd_vel", f"cmd_vel ignored: {reason}")

    def _on_twist(self, msg: Twist) -> None:
        self._apply_velocity(msg.linear.x, msg.angular.z)

    def _on_twist_stamped(self, msg: TwistStamped) -> None:
        self._apply_velocity(msg.twist.linear.x, msg.twist.angular.z)

    # --- publishers (loop thread) ------------------------------------------------------------------------------
    def _too_soon(self, topic: str) -> bool:
        return self._throttle.too_soon(topic)

    def _publish_clock(self, now: float) -> None:
        if self.clock_pub is None or self._too_soon("clock") or self.clock_pub.get_subscription_count() == 0:
            return
        set_time(self._clock.clock, now)
        self.clock_pub.publish(self._clock)

    def _publish_static(self, now: float) -> None:
        f = self.frames
        laser = transform(f["base"], f["laser"], LASER_OFFSET[0], LASER_OFFSET[1], 0.0, now, LASER_OFFSET[2])
        self.tf_static_pub.publish(TFMessage(transforms=[laser]))

    def _publish_odom(self, now: float) -> None:
        if self._too_soon("odom"):  # before the subscription counts, which cost more
            return
        want_odom = self.odom_pub.get_subscription_count() > 0
        want_tf = self.tf_pub.get_subscription_count() > 0
        if not (want_odom or want_tf):
            return
        f = self.frames
        o = self.sim.odometry()
        if want_odom:
            msg = self._odom
            set_time(msg.header.stamp, now)
            msg.pose.pose.position.x = float(o.x)
            msg.pose.pose.position.y = float(o.y)
            set_yaw(msg.pose.pose.orientation, float(o.yaw))
            msg.twist.twist.linear.x = float(o.v)
            msg.twist.twist.angular.z = float(o.w)
            self.odom_pub.publish(msg)
        if want_tf:
            transforms = [transform(f["odom"], f["base"], o.x, o.y, o.yaw, now)]
            map_to_odom = self.loop.nav.localizer.map_to_odom()
            if map_to_odom is not None:
                transforms.append(transform(f["map"], f["odom"], *map_to_odom, now))
            self.tf_pub.publish(TFMessage(transforms=transforms))

    def _publish_scan(self, now: float) -> None:
        if self._too_soon("scan") or self.scan_pub.get_subscription_count() == 0:
            return
        s = self.sim.scan()
        msg = self._scan
        set_time(msg.header.stamp, now)
        msg.angle_min = float(s.angle_min)
        msg.angle_max = float(s.angle_max)
        msg.angle_increment = float(s.angle_increment)
        msg.range_min = float(s.range_min)
        msg.range_max = float(s.range_max)
        ranges = array.array("f")  # an array.array skips the generated setter's per-element checks
        ranges.frombytes(np.ascontiguousarray(s.ranges, dtype=np.float32).tobytes())
        msg.ranges = ranges
        self.scan_pub.publish(msg)

    def _publish_battery(self, now: float) -> None:
        if self.battery_pub.get_subscription_count() == 0:
            return
        b = self.sim.battery()
        msg = self._battery
        # the charge differs in every message, so only a change of state (charging, discharging, full) goes out at
        # once and the rest at most 50 times a wall second: charging at --rate max sent 300 to 600 a wall second
        if self._throttle.repeat_too_soon("battery_state", int(b.power_supply_status) == msg.power_supply_status):
            return
        set_time(msg.header.stamp, now)
        msg.voltage = float(b.voltage)
        msg.temperature = float(b.temperature)
        msg.current = float(b.current)
        msg.charge = float(b.charge)
        msg.capacity = float(b.capacity)
        msg.design_capacity = float(b.design_capacity)
        msg.percentage = float(b.percentage)
        msg.power_supply_status = int(b.power_supply_status)
        self.battery_pub.publish(msg)

    def _publish_dock_status(self, now: float) -> None:
        if self.dock_pub.get_subscription_count() == 0:
            return
        visible, docked = bool(self.sim.dock_visible()), bool(self.sim.is_docked())
        key = bytes((visible, docked))
        if self._throttle.repeat_too_soon("dock_status", self._dock_status.repeats(key)):
            return

        def fill(msg: DockStatus) -> None:
            msg.dock_visible, msg.is_docked = visible, docked

        self.dock_pub.publish(self._dock_status.serialized(now, key, fill))

    def _report_hazards(self, now: float) -> None:
        for event in self.sim.pop_hazards():
            self.bumps += 1
            self.warn_limited("bump", f"bump at ({event.x:.2f}, {event.y:.2f}) t={event.time:.1f}s")
            if self.record is not None:
                self.record.note("bump", event.time, x=round(event.x, 3), y=round(event.y, 3))
