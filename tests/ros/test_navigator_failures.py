"""Failure paths of the navigator over DDS: no server, bad arguments, rejection, failure, cancel, preemption,
undock when not docked, and a navigator spun by the user's own executor."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import NavigateToPose
from nav2_msgs.srv import ManageLifecycleNodes
from nav_msgs.msg import Odometry, Path
from rclpy.qos import qos_profile_sensor_data

from tb4.navigator import NavigatorTimeout, NavigatorTimeouts, TaskResult, TurtleBot4Directions
from tb4.wire import result_code

from .test_navigator_tasks import Pose, make_navigator, run_to_end, start_localized

D = TurtleBot4Directions
__all__ = ["make_navigator"]  # the fixture, imported for this module's tests


def _deep_inside_a_wall(world: str) -> tuple[float, float]:
    from scipy.ndimage import distance_transform_edt

    from tb4.sim.world import load_world

    grid = load_world(world).map
    depth = distance_transform_edt(grid.occupied_mask()) * grid.resolution
    row, col = np.unravel_index(int(np.argmax(depth)), depth.shape)
    return grid.cell_to_world(int(row), int(col))


def test_no_server_fails_within_the_limit_and_bad_arguments_fail_first(make_navigator) -> None:
    limits = NavigatorTimeouts(server=1.0, lifecycle=1.0, dock_status=0.5, clock_discovery=0)
    nav = make_navigator(namespace="nobody", timeouts=limits)
    assert not nav.uses_sim_time
    goal = nav.getPoseStamped([1.0, 2.0], D.WEST)

    started = time.monotonic()
    with pytest.raises(NavigatorTimeout) as info:
        nav.goToPose(goal)
    assert time.monotonic() - started < 6.0  # 1 s limit, generous slack for a loaded machine
    message = str(info.value)
    assert "'navigate_to_pose'" in message and "'/nobody'" in message and "simulator or Nav2 running" in message

    with pytest.raises(NavigatorTimeout, match="amcl/get_state"):
        nav.waitUntilNav2Active()
    with pytest.raises(NavigatorTimeout, match="dock_status"):
        nav.getDockedStatus()
    with pytest.raises(NavigatorTimeout, match="map_server/load_map"):
        nav.changeMap("/tmp/map.yaml")
    with pytest.raises(NavigatorTimeout, match="'dock'"):
        nav.dock()
    with pytest.raises(NavigatorTimeout, match="ManageLifecycleNodes"):
        nav.lifecycleStartup()

    nan_goal = nav.getPoseStamped([0.0, 0.0], D.NORTH)
    nan_goal.pose.position.x = math.nan
    for call, error in [
        (lambda: nav.goToPose(nan_goal), ValueError),
        (lambda: nav.goToPose([1.0, 2.0]), TypeError),
        (lambda: nav.goThroughPoses([]), ValueError),
        (lambda: nav.followWaypoints([]), ValueError),
        (lambda: nav.followWaypoints([goal], goal_index=3), ValueError),
        (lambda: nav.followPath(Path()), ValueError),
        (lambda: nav.spin("left"), TypeError),
        (lambda: nav.spin(math.inf), ValueError),
        (lambda: nav.backup(0.2, 0.0), ValueError),
        (lambda: nav.driveOnHeading(0.2, 0.1, time_allowance=-1), ValueError),
        (lambda: nav.getPoseStamped([1.0], 0), ValueError),
        (lambda: nav.getPoseStamped([math.nan, 0.0], 0), ValueError),
        (lambda: nav.getPoseStamped([0.0, 0.0], "UP"), ValueError),
        (lambda: nav.getPoseStamped([0.0, 0.0], None), TypeError),
        (lambda: nav.setInitialPose(None), TypeError),
        (lambda: nav.smoothPath(Path()), ValueError),
        (lambda: nav.changeMap(3), TypeError),
        (lambda: nav.getPath(None, PoseStamped(), use_start=True), TypeError),
        (lambda: nav.stampPose(goal), TypeError),
    ]:
        with pytest.raises(error):
            call()
    # Direction names are accepted as well as degrees.
    west = nav.getPoseStamped([0.0, 0.0], "west").pose.orientation
    assert (west.z, west.w) == pytest.approx((math.sin(math.pi / 4), math.cos(math.pi / 4)))


def test_rejected_failed_canceled_and_preempted_goals(start_simulator, ros, make_navigator, capfd) -> None:
    # 10x: the cancel and the preemption below must come while the robot drives; at --rate max the whole drive can
    # end within one starved wall second of the test's thread on a loaded machine (a run under load saw it at the goal)
    start_simulator("--rate", "10", "--world", "warehouse")
    nav = make_navigator()
    pose = Pose(ros)
    start_localized(nav)
    assert nav.spin(0.5)
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED

    # Rejected (navigator paused): None at once (Kilted), nothing stale left from the spin before.
    pause = ManageLifecycleNodes.Request(command=ManageLifecycleNodes.Request.PAUSE)
    assert ros.service(ManageLifecycleNodes, "lifecycle_manager_navigation/manage_nodes", pause).success
    assert nav.goToPose(nav.getPoseStamped([-3.0, 0.0], D.EAST)) is None
    assert nav.isTaskComplete() and nav.getResult() is TaskResult.UNKNOWN and nav.getFeedback() is None
    assert nav.isTaskComplete(task=None) and nav.getFeedback(task=None) is None  # Kilted style, rejected task
    code, msg = nav.getTaskError()
    assert code == result_code(NavigateToPose, "UNKNOWN") and msg == "NavigateToPose goal to -3.0 0.0 was rejected!"
    assert nav.startToPose(nav.getPoseStamped([-3.0, 0.0], D.EAST)) is TaskResult.UNKNOWN
    resume = ManageLifecycleNodes.Request(command=ManageLifecycleNodes.Request.RESUME)
    assert ros.service(ManageLifecycleNodes, "lifecycle_manager_navigation/manage_nodes", resume).success

    # Failed: the goal lies deep inside a wall; the error code and message come through getTaskError.
    x, y = _deep_inside_a_wall("warehouse")
    capfd.readouterr()
    assert nav.startToPose(nav.getPoseStamped([x, y], D.NORTH)) is TaskResult.FAILED
    code, msg = nav.getTaskError()
    assert code == 206 and msg  # ComputePathToPose GOAL_OCCUPIED
    assert "Goal failed! status ABORTED, error 206" in capfd.readouterr().err
    assert nav.getPath(None, nav.getPoseStamped([-40.0, 0.0], D.NORTH)) is None
    assert nav.getTaskError()[0] == 204  # GOAL_OUTSIDE_MAP

    # Canceled: the robot stops.
    odom = ros.latest(Odometry, "odom", qos_profile_sensor_data)
    ros.wait_for(odom, what="odom")  # matched before the goal
    assert nav.goToPose(nav.getPoseStamped([-13.0, 9.0], D.EAST))
    ros.wait_for(odom, lambda m: abs(m.twist.twist.linear.x) > 0.1, what="robot moving")
    nav.cancelTask()
    run_to_end(nav)
    assert nav.getResult() is TaskResult.CANCELED
    ros.wait_for(odom, lambda m: abs(m.twist.twist.linear.x) < 0.01, what="robot stopped")

    # Preempted: a new goal replaces the running one; the old goal's end does not overwrite the new result.
    assert nav.goToPose(nav.getPoseStamped([-13.0, 9.0], D.EAST))
    ros.wait_for(odom, lambda m: abs(m.twist.twist.linear.x) > 0.1, what="robot moving")
    assert nav.goToPose(nav.getPoseStamped([-1.0, -1.0], D.NORTH))
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    pose.near(-1.0, -1.0)
    time.sleep(0.3)
    assert nav.isTaskComplete() and nav.getResult() is TaskResult.SUCCEEDED

    # Undock when not docked: the Create 3 rejects it; we say why and return False.
    capfd.readouterr()
    assert nav.undock() is False
    assert "not docked" in nav.getTaskError()[1]
    assert "Undock goal rejected" in capfd.readouterr().err
    assert nav.undockRobot()
    run_to_end(nav)
    assert nav.getResult() is TaskResult.FAILED and nav.getTaskError()[0] == 902


def test_navigator_in_the_users_executor(start_simulator, ros, make_navigator) -> None:
    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    start_simulator("--rate", "max", "--world", "warehouse")
    nav = make_navigator()
    pose = Pose(ros)
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(nav)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        start_localized(nav)
        assert nav.goToPose(nav.getPoseStamped([-2.0, 0.0], D.EAST))
        run_to_end(nav)
        assert nav.getResult() is TaskResult.SUCCEEDED
        pose.near(-2.0, 0.0)
    finally:
        stop.set()
        thread.join(timeout=5)
        executor.remove_node(nav)
        executor.shutdown(timeout_sec=1)
    # Let go of by the user's executor, the navigator spins itself again, also after rclpy.spin_once on it.
    rclpy.spin_once(nav, timeout_sec=0.1)
    assert nav.goToPose(nav.getPoseStamped([-2.0, -1.0], D.NORTH))
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    state = ros.service(GetState, "bt_navigator/get_state", GetState.Request())
    assert state.current_state.label == "active"
