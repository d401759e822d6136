"""The upstream tutorial programs (our rewrites, upstream import paths only) run unchanged against `tb4 sim`:
the TurtleBot 4 tutorials (Jazzy-era call style) and Kilted-style Simple Commander scripts (kilted_*.py, written
like Nav2's Kilted examples: RunningTask handles, isTaskComplete(task=...), getFeedback(task=...))."""

from __future__ import annotations

import math
import subprocess
import sys
import time
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.msg import DockStatus
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import ComputePathToPose
from rclpy.duration import Duration
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

from tb4.nav.route_graph import load_route_graph
from tb4.ros.convert import pose_msg
from tb4.sim.world import load_world
from tb4.wire import wire_format

SCRIPTS = Path(__file__).parent / "upstream_scripts"
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
# as fast as it goes once the script acts; until its first command the simulator runs at real time (as under
# `tb4 run`), instead of burning a core on the dock while the script's process starts and discovers it: a third
# of these tests' CPU, which the other tests running beside them need
FAST = ("--rate", "max", "--hold")


def run_script(start_process, name: str, *, stdin: bytes | None = None, env: dict | None = None, timeout=240):
    """Run SCRIPTS/name as a child process; returns (exit code, output). stdin is written then closed."""
    kwargs = {"stdin": subprocess.PIPE} if stdin is not None else {}
    if env:
        import os

        kwargs["env"] = {**os.environ, "PYTHONFAULTHANDLER": "1", **env}
    proc = start_process([sys.executable, str(SCRIPTS / name)], name=name.removesuffix(".py"), **kwargs)
    if stdin is not None:
        proc.popen.stdin.write(stdin)
        proc.popen.stdin.close()
    try:
        code = proc.popen.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.abort_showing_stacks()  # where it hung, in its output
        raise AssertionError(f"{name} did not finish in {timeout} s:\n{proc.output()[-6000:]}") from None
    return code, proc.output()


def final_pose(ros) -> tuple[float, float]:
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    p = ros.wait_for(amcl, what="amcl_pose").pose.pose.position
    return p.x, p.y


def docked(ros) -> bool:
    status = ros.latest(DockStatus, "dock_status", qos_profile_sensor_data)
    return bool(ros.wait_for(status, what="dock_status").is_docked)


def near(pose: tuple[float, float], x: float, y: float, tol: float = 0.35) -> bool:
    return math.hypot(pose[0] - x, pose[1] - y) < tol


def test_nav_to_pose(start_simulator, start_process, ros) -> None:
    # 20x, not max: the ETA line goes out every 5th poll of isTaskComplete, and at --rate max the whole crossing
    # can now end within fewer polls (1.1 s wall)
    start_simulator("--rate", "20", "--world", "warehouse")
    code, out = run_script(start_process, "nav_to_pose.py")
    assert code == 0, out[-3000:]
    assert "Nav2 is ready for use!" in out and "Undock succeeded" in out and "Goal succeeded!" in out
    assert "Estimated time of arrival:" in out
    assert near(final_pose(ros), -13.0, 9.0)


def test_nav_through_poses_then_dock(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse")
    code, out = run_script(start_process, "nav_through_poses.py")
    assert code == 0, out[-3000:]
    assert "Navigating with 6 goals" in out and "Goal succeeded!" in out and "Dock succeeded" in out, out[-3000:]
    assert docked(ros)


def test_follow_waypoints_in_the_depot_then_dock(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "depot")
    code, out = run_script(start_process, "follow_waypoints.py")
    assert code == 0, out[-3000:]
    # (how many 'Executing current waypoint' lines appear depends on the speed-up, so they are not asserted)
    assert "Following 4 goals" in out and "Goal succeeded!" in out and "Dock succeeded" in out, out[-3000:]
    assert docked(ros)


def test_mail_delivery_driven_from_stdin(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse")
    code, out = run_script(start_process, "mail_delivery.py", stdin=b"mail\n9\n4\n0\n5\n")
    assert code == 0, out[-3000:]
    assert "Invalid goal selection: mail" in out and "Goal selection out of bounds: 9" in out
    assert out.count("Goal succeeded!") == 2, out[-3000:]
    assert near(final_pose(ros), -1.0, 1.0)


def test_patrol_loop_one_lap(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse")
    code, out = run_script(start_process, "patrol_loop.py", env={"PATROL_LAPS": "1"}, timeout=300)
    assert code == 0, out[-3000:]
    assert out.count("Goal succeeded!") == 4 and "Patrol finished after 1 lap(s)" in out, out[-3000:]
    assert "Battery is at" in out
    assert near(final_pose(ros), 10.0, 2.0)


def test_patrol_loop_stops_on_a_critical_battery(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse", "--battery", "0.05")  # held: no charging before
    code, out = run_script(start_process, "patrol_loop.py", env={"PATROL_LAPS": "1"})
    assert code == 0, out[-3000:]
    assert "Battery critically low. Charge or power down" in out and "Goal succeeded!" not in out


def test_create_path_from_pose_estimates(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse")
    proc = start_process([sys.executable, str(SCRIPTS / "create_path.py")], name="create_path", stdin=subprocess.PIPE)
    try:
        assert proc.wait_for_output("Creating a path. Press Enter to finish.", timeout=60), proc.output()
        publisher = ros.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        deadline = time.monotonic() + 20
        while publisher.get_subscription_count() < 2:  # the localizer's and the script's subscriptions
            assert time.monotonic() < deadline, "the script's initialpose subscription was not discovered"
            time.sleep(0.05)
        targets = [(-2.0, 0.0, math.pi), (-2.0, -2.0, 0.0), (-1.0, 0.0, 0.0)]
        for i, (x, y, yaw) in enumerate(targets, start=1):
            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = "map"
            msg.pose.pose = pose_msg(x, y, yaw)
            publisher.publish(msg)  # once: reliable delivery to matched readers, as RViz's tool does
            assert publisher.wait_for_all_acked(Duration(seconds=10))
            deadline = time.monotonic() + 20
            while proc.output().count("Pose added.") < i:
                assert time.monotonic() < deadline, proc.output()
                time.sleep(0.05)
        assert proc.output().count("Pose added.") == len(targets)
        proc.popen.stdin.write(b"\n")
        proc.popen.stdin.flush()
        code = proc.popen.wait(180)
    finally:
        out = proc.output()
        proc.stop()
    assert code == 0, out[-3000:]
    assert "Pose 2 [x,y]=[-1.000,0.000]" in out
    # (how many 'Executing current waypoint' lines appear depends on the speed-up, so they are not asserted)
    assert "Following 3 goals" in out and "Goal succeeded!" in out and "Dock succeeded" in out, out[-3000:]
    assert docked(ros)


def run_kilted(start_simulator, start_process, name: str) -> str:
    start_simulator(*FAST, "--world", "warehouse")
    code, out = run_script(start_process, name)
    assert code == 0 and "Traceback" not in out, out[-3000:]
    return out


def test_kilted_nav_to_pose_inside_succeeds_outside_fails_with_nav2s_code(start_simulator, start_process, ros):
    out = run_kilted(start_simulator, start_process, "kilted_nav_to_pose.py")
    assert "Goal inside succeeded!" in out, out[-3000:]
    assert f"Goal outside failed!{ComputePathToPose.Result.GOAL_OUTSIDE_MAP}:" in out, out[-3000:]
    assert near(final_pose(ros), -13.0, 9.0)


def test_kilted_follow_path(start_simulator, start_process, ros) -> None:
    out = run_kilted(start_simulator, start_process, "kilted_follow_path.py")
    assert "Planned" in out and "Goal succeeded!" in out, out[-3000:]
    assert near(final_pose(ros), -2.0, -2.0)


def test_kilted_waypoint_follower(start_simulator, start_process, ros) -> None:
    pose = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)  # before the script shuts Nav2 down
    out = run_kilted(start_simulator, start_process, "kilted_waypoint_follower.py")
    state = ros.service(GetState, "bt_navigator/get_state", GetState.Request()).current_state.label
    assert state == "finalized", f"lifecycleShutdown left bt_navigator {state}"
    p = ros.wait_for(pose, what="amcl_pose").pose.pose.position
    assert near((p.x, p.y), -1.0, 1.0)
    # (which waypoints the feedback showed depends on the speed-up: getFeedback keeps only the latest message)
    assert "Goal succeeded!" in out and "Waypoints reported in feedback: [" in out, out[-3000:]


def test_kilted_recoveries(start_simulator, start_process, ros) -> None:
    # At 10x: the script cancels assisted teleop after 1 s of it, and 19 simulated seconds of margin must outlast
    # the cancel's round trip (at full speed they pass in a fraction of a wall second).
    start_simulator("--rate", "10", "--world", "warehouse")
    code, out = run_script(start_process, "kilted_recoveries.py")
    assert "Traceback" not in out, out[-3000:]
    assert code == 0, out[-3000:]
    for line in ("Backup: SUCCEEDED", "Spin: SUCCEEDED", "Drive on heading: SUCCEEDED", "Assisted teleop: CANCELED"):
        assert line in out, out[-3000:]
    assert "Return to start: SUCCEEDED" in out and near(final_pose(ros), 0.0, 0.0)


def test_kilted_picking(start_simulator, start_process, ros) -> None:
    out = run_kilted(start_simulator, start_process, "kilted_picking.py")
    assert "Got product from shelf_A!" in out and "Product delivered to home!" in out, out[-3000:]
    assert near(final_pose(ros), -1.0, 1.0)


@pytest.mark.skipif(
    wire_format() == "jazzy", reason="a Kilted script: it reads Kilted's WaypointStatus fields of missed_waypoints"
)
def test_kilted_inspection_misses_only_the_point_outside_the_map(start_simulator, start_process, ros) -> None:
    out = run_kilted(start_simulator, start_process, "kilted_inspection.py")
    assert "Missed waypoints: [2]" in out and "Back at the start: SUCCEEDED" in out, out[-3000:]


def test_kilted_route(start_simulator, start_process, ros) -> None:
    start_simulator(*FAST, "--world", "warehouse")
    code, out = run_script(start_process, "kilted_route.py")
    assert code == 0 and "Traceback" not in out, out[-3000:]
    assert "Route with" in out and "Passing new route to controller!" in out, out[-3000:]
    assert "Goal succeeded!" in out, out[-3000:]
    # As on Nav2's route server, a route runs node to node: it ends at the graph node nearest the goal pose.
    graph = load_route_graph(load_world("warehouse").route_graph)
    (goal_node,) = graph.nearest_nodes(-13.0, 9.0)
    assert near(final_pose(ros), graph.nodes[goal_node].x, graph.nodes[goal_node].y)


def test_jazzy_style_calls_on_the_same_navigator(start_simulator, start_process, ros) -> None:
    out = run_kilted(start_simulator, start_process, "jazzy_nav_through_poses.py")
    assert "Path through 2 poses" in out and "Through poses: TaskResult.SUCCEEDED" in out, out[-3000:]
    assert "Waypoints: TaskResult.SUCCEEDED" in out and near(final_pose(ros), -1.0, 1.0)


@pytest.mark.parametrize("script", sorted(p.name for p in SCRIPTS.glob("*.py")))
def test_scripts_use_only_upstream_import_paths(script: str) -> None:
    text = (SCRIPTS / script).read_text()
    assert "tb4" not in text.replace("TurtleBot4", "")
    if script.startswith("kilted_"):
        assert "from nav2_simple_commander.robot_navigator import" in text
        assert "isTaskComplete(task=" in text and "isTaskComplete()" not in text
    elif script.startswith("jazzy_"):
        assert "from nav2_simple_commander.robot_navigator import" in text
        assert "isTaskComplete()" in text and "task=" not in text
    else:
        assert "from turtlebot4_navigation.turtlebot4_navigator import" in text
