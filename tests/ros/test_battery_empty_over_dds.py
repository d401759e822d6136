"""An empty battery is not silent, over real DDS: the battery runs flat during a navigation goal, which fails naming
the battery; the simulator says so once in its log, on wheel_status and battery_state, and in the run record; every
later goal fails at once (not after the progress checker's 10 s); on the dock the robot charges and drives again."""

from __future__ import annotations

import json
import time

from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.action import DriveDistance, Undock
from irobot_create_msgs.msg import WheelStatus
from nav2_msgs.action import NavigateToPose, Spin
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import BatteryState

from tb4.processes import tb4_command
from tb4.sim.create3 import BATTERY_EMPTY

from .rosclient import navigate_to_pose_goal

SUCCEEDED, ABORTED, REJECTED = 4, 6, -1
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
LOADING_BAY = (2.0, -23.0)  # 23 m south of the dock: far more than the battery lasts


def test_a_flat_battery_fails_goals_naming_it_and_the_dock_brings_it_back(
    start_simulator, start_process, ros, tmp_path
) -> None:
    record = tmp_path / "run.json"
    # 0.2 % of 26 Wh, docked (charging while held at real time): seconds of driving, a minute at most: not 23 m
    sim = start_simulator(
        "--rate", "max", "--world", "warehouse", "--battery", "0.002", "--hold", "--record-run", str(record)
    )
    wheels = ros.latest(WheelStatus, "wheel_status")
    battery = ros.latest(BatteryState, "battery_state")
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    initial = PoseWithCovarianceStamped()
    initial.header.frame_id = "map"
    initial.pose.pose.orientation.w = 1.0
    ros.publish_until(PoseWithCovarianceStamped, "initialpose", initial, amcl, what="amcl_pose")
    ros.action_client(NavigateToPose, "navigate_to_pose")  # discovered ahead of the goals that must fail at once
    ros.action_client(Spin, "spin")
    assert ros.action(Undock, "undock", Undock.Goal())[0] == SUCCEEDED

    status, result = ros.action(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(*LOADING_BAY), timeout=120.0)
    assert (status, result.error_code, result.error_msg) == (ABORTED, 9000, BATTERY_EMPTY), sim.output()[-3000:]
    assert sim.wait_for_output("The battery is empty (0 %)", timeout=10), sim.output()[-3000:]
    out = sim.output()
    assert out.count("The battery is empty (0 %)") == 1 and "battery low (" in out, out[-3000:]
    assert "failed to make progress" not in out
    assert not ros.wait_for(wheels, lambda m: not m.wheels_enabled, what="wheels disabled").wheels_enabled
    flat = ros.wait_for(battery, lambda m: m.percentage == 0.0, what="battery_state at 0 %")
    assert flat.power_supply_status == BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING

    # every later goal that drives fails at once with the same reason
    began = time.monotonic()
    status, result = ros.action(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(1.0, 1.0), timeout=30.0)
    assert (status, result.error_msg) == (ABORTED, BATTERY_EMPTY)
    status, result = ros.action(Spin, "spin", Spin.Goal(target_yaw=1.0), timeout=30.0)
    assert (status, result.error_code, result.error_msg) == (ABORTED, 700, BATTERY_EMPTY)
    assert time.monotonic() - began < 8.0  # no 10 s progress checker twice over
    assert ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=0.2))[0] == REJECTED
    assert sim.wait_for_output(f"drive_distance goal rejected: {BATTERY_EMPTY}", timeout=10)

    # put on the dock by hand: it charges, the motors come back, and the log says so
    kidnap = start_process(tb4_command("kidnap", "0", "0", "0"), name="kidnap")
    assert kidnap.popen.wait(30) == 0, kidnap.output()
    ros.wait_for(wheels, lambda m: m.wheels_enabled, timeout=30, what="wheels enabled on the dock")
    charging = ros.wait_for(battery, lambda m: m.percentage > 0.0, timeout=30, what="charging")
    assert charging.power_supply_status in (  # at --rate max a charge of hours takes seconds
        BatteryState.POWER_SUPPLY_STATUS_CHARGING,
        BatteryState.POWER_SUPPLY_STATUS_FULL,
    )
    assert sim.wait_for_output("battery charging on the dock: the motors are enabled again", timeout=10)

    assert sim.stop() == 0
    events = json.loads(record.read_text())["events"]
    flat_events = [e for e in events if e["type"] == "battery_empty"]
    assert len(flat_events) == 1 and flat_events[0]["message"] == BATTERY_EMPTY, flat_events
    failed = [e for e in events if e["type"] == "result" and e["action"] == "navigate_to_pose"][0]
    assert failed["error_msg"] == BATTERY_EMPTY and 0.0 < flat_events[0]["t"] <= failed["t"]
    assert {"battery_low", "battery_charging"} <= {e["type"] for e in events}
