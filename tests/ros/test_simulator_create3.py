"""The simulator process serves the Create 3 side over real DDS: undock, dock, and the topics that follow."""

from __future__ import annotations

import math
import time

from geometry_msgs.msg import Twist, Vector3
from irobot_create_msgs.action import Dock, Undock
from irobot_create_msgs.msg import DockStatus
from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, LaserScan
from tf2_msgs.msg import TFMessage

SUCCEEDED, ABORTED, REJECTED = 4, 6, -1


def test_undock_then_dock_changes_dock_status_odom_and_battery(start_simulator, ros) -> None:
    sim = start_simulator("--rate", "20", "--world", "depot", "--battery", "0.5")
    dock_status = ros.latest(DockStatus, "dock_status", qos_profile_sensor_data)
    battery = ros.latest(BatteryState, "battery_state", qos_profile_sensor_data)
    odom = ros.latest(Odometry, "odom", qos_profile_sensor_data)
    scan = ros.latest(LaserScan, "scan", qos_profile_sensor_data)
    clock = ros.latest(Clock, "/clock")
    tf = ros.latest(TFMessage, "tf")

    assert ros.wait_for(dock_status, what="dock_status").is_docked
    first_battery = ros.wait_for(battery, what="battery_state")
    assert first_battery.power_supply_status in (
        BatteryState.POWER_SUPPLY_STATUS_CHARGING,
        BatteryState.POWER_SUPPLY_STATUS_FULL,
    )
    assert math.isclose(first_battery.percentage, 0.5, abs_tol=0.02)
    s = ros.wait_for(scan, what="scan")
    assert len(s.ranges) == 360 and s.header.frame_id
    assert ros.wait_for(clock, what="clock").clock.sec >= 0
    assert any(t.child_frame_id == "base_link" for t in ros.wait_for(tf, what="tf").transforms)

    # Dock while docked: rejected, like a Create 3.
    status, _ = ros.action(Dock, "dock", Dock.Goal())
    assert status == REJECTED

    status, result = ros.action(Undock, "undock", Undock.Goal())
    assert status == SUCCEEDED and result.is_docked is False
    undocked = ros.wait_for(dock_status, lambda m: not m.is_docked, what="undocked status")
    assert not undocked.is_docked
    o = ros.wait_for(odom, lambda m: m.pose.pose.position.x < -0.3, what="odom after undock")
    assert -0.5 < o.pose.pose.position.x < -0.3  # reversed about 0.4 m
    discharging = ros.wait_for(
        battery,
        lambda m: m.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING,
        what="discharging battery",
    )
    assert discharging.current < 0

    # Undock again: rejected (not docked).
    status, _ = ros.action(Undock, "undock", Undock.Goal())
    assert status == REJECTED

    # After undocking the robot faces away from the dock, which it cannot see: dock is rejected.
    status, _ = ros.action(Dock, "dock", Dock.Goal())
    assert status == REJECTED

    # Turn back towards the dock with cmd_vel (Twist), then dock: the robot drives in and charges.
    cmd = ros.node.create_publisher(Twist, "cmd_vel", 10)
    bad = Twist()
    bad.angular.z = float("nan")
    cmd.publish(bad)  # ignored with a warning, never a crash

    def facing_dock(m: Odometry) -> bool:
        cmd.publish(Twist(angular=Vector3(z=0.6)))
        return abs(_yaw(m)) < 0.08

    ros.wait_for(odom, facing_dock, timeout=30, what="robot turned towards the dock")
    cmd.publish(Twist())
    ros.wait_for(dock_status, lambda m: m.dock_visible, what="dock visible")
    feedback: list = []
    status, result = ros.action(Dock, "dock", Dock.Goal(), feedback=feedback)
    assert status == SUCCEEDED and result.is_docked is True
    assert ros.wait_for(dock_status, lambda m: m.is_docked, what="docked status").is_docked
    charging = ros.wait_for(
        battery, lambda m: m.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING, what="charging"
    )
    assert charging.current > 0
    assert sim.alive()


def _yaw(m: Odometry) -> float:
    q = m.pose.pose.orientation
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def test_battery_state_at_a_high_rate_is_bounded_per_wall_second_and_still_reports_the_charge(
    start_simulator, ros
) -> None:
    # 500x, not max: at max a robot resting on its dock is fast-forwarded (SimLoop.idle_periods) and would be
    # full before the window below ends. From 5 % a charge takes 2.4 h of sim time, 17 s of wall time at 500x: the
    # window ends long before full even when the first message takes seconds to come (from 30 % at 1000x, a loaded
    # machine's slow discovery let the battery fill up, and a FULL message ended in the window)
    start_simulator("--rate", "500", "--battery", "0.05")
    received: list[BatteryState] = []
    ros.node.create_subscription(BatteryState, "battery_state", received.append, qos_profile_sensor_data)
    ros.wait_for(lambda: received[-1] if received else None, what="battery_state")
    start, count = time.monotonic(), len(received)
    time.sleep(2.0)
    window = received[count:]
    wall = time.monotonic() - start
    # at most 50 a wall second (a change of state aside), where charging at hundreds of times real time sent one
    # per sim second: hundreds a wall second
    assert len(window) <= 50 * wall + 10, f"{len(window)} battery_state messages in {wall:.1f} s"
    assert window, "no battery_state for 2 s"
    assert all(m.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_CHARGING for m in window)
    assert window[-1].percentage > received[0].percentage  # the charge still goes up in what is sent
