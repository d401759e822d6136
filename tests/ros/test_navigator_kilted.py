"""The Kilted-only navigator methods over DDS, against raw-rclpy servers as Nav2 serves them (tests/ros/fake_nav2):
what goal the navigator sends, and how it handles feedback, results, error codes, rejection, cancel and timeouts.
Called the way Nav2's Kilted examples call them: RunningTask handles, isTaskComplete(task=...),
getFeedback(task=...)."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
from geographic_msgs.msg import GeoPose
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import (
    ComputeAndTrackRoute,
    ComputeRoute,
    DockRobot,
    FollowGPSWaypoints,
    FollowPath,
    NavigateToPose,
    UndockRobot,
)
from nav2_msgs.msg import Route, RouteNode
from nav_msgs.msg import Path

from tb4.navigator import BasicNavigator, NavigatorTimeout, NavigatorTimeouts, RunningTask, TaskResult
from tb4.wire import get_poses, result_code, wire_format

from .fake_nav2 import FakeNav2, Script
from .wire_checks import result_with, sent_message

FAST = NavigatorTimeouts(server=5.0, response=3.0, result=10.0, clock_discovery=0.0)


@pytest.fixture
def fake() -> Iterator[FakeNav2]:
    servers = FakeNav2()
    yield servers
    servers.close()


@pytest.fixture
def nav() -> Iterator[BasicNavigator]:
    import rclpy

    if not rclpy.ok():
        rclpy.init()
    navigator = BasicNavigator(timeouts=FAST)
    yield navigator
    navigator.destroyNode()
    rclpy.try_shutdown()


def pose(x: float, y: float, yaw: float = 0.0) -> PoseStamped:
    p = PoseStamped()
    p.header.frame_id = "map"
    p.pose.position.x, p.pose.position.y = x, y
    p.pose.orientation.z, p.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    return p


def path(*points: tuple[float, float]) -> Path:
    msg = Path()
    msg.header.frame_id = "map"
    msg.poses = [pose(x, y) for x, y in points]
    return msg


def wait_done(nav: BasicNavigator, task: Any, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not nav.isTaskComplete(task=task):
        assert time.monotonic() < deadline, f"{task} did not complete"


def route_feedback(last: int, nxt: int, rerouted: bool, along: Path) -> Any:
    return ComputeAndTrackRoute.Feedback(
        last_node_id=last, next_node_id=nxt, current_edge_id=100 + last, path=along, rerouted=rerouted
    )


def test_route_tracking_beside_follow_path_as_example_route_does(fake: FakeNav2, nav: BasicNavigator) -> None:
    route_server = fake.action(ComputeAndTrackRoute, "compute_and_track_route")
    follow = fake.action(FollowPath, "follow_path")
    road = path((0.0, 0.0), (1.0, 0.0), (2.0, 0.0))
    route_server.scripts.append(
        Script(feedback=[route_feedback(i, i + 1, i == 0, road) for i in range(5)], outcome="hold")
    )
    follow.scripts.append(Script(feedback=[FollowPath.Feedback(distance_to_goal=1.0, speed=0.2)] * 3))

    task = nav.getAndTrackRoute(pose(0.0, 0.0), pose(2.0, 0.0, math.pi))
    assert task is RunningTask.COMPUTE_AND_TRACK_ROUTE
    sent = route_server.goals[-1]
    assert sent.use_poses and not sent.use_start and sent.goal.pose.position.x == 2.0

    # Every route feedback, in order, one per getFeedback; the rerouted one carries the path for the controller.
    seen: list[Any] = []
    follow_task = RunningTask.NONE
    deadline = time.monotonic() + 20
    while len(seen) < 5:
        assert time.monotonic() < deadline, f"only {len(seen)} route feedback messages"
        assert not nav.isTaskComplete(task=task)
        feedback = nav.getFeedback(task=task)
        while feedback is not None:
            seen.append(feedback)
            if feedback.rerouted:
                follow_task = nav.followPath(feedback.path)
            feedback = nav.getFeedback(task=task)
    assert [f.last_node_id for f in seen] == [0, 1, 2, 3, 4] and nav.getFeedback(task=task) is None
    assert follow_task is RunningTask.FOLLOW_PATH and len(follow.goals[-1].path.poses) == 3

    # The controller finishes while the route is still tracked; the route keeps running until canceled.
    wait_done(nav, follow_task)
    assert nav.getResult() is TaskResult.SUCCEEDED and not nav.isTaskComplete(task=task)
    nav.cancelTask()
    wait_done(nav, task)
    assert route_server.canceled.is_set() and nav.getResult() is TaskResult.CANCELED


def test_route_requests_by_id_mixed_and_out_of_range(fake: FakeNav2, nav: BasicNavigator) -> None:
    route_server = fake.action(ComputeAndTrackRoute, "compute_and_track_route")
    no_route = ComputeAndTrackRoute.Result.NO_VALID_ROUTE
    failed = result_with(ComputeAndTrackRoute, error_code=no_route, error_msg="no way")
    route_server.scripts.append(Script(outcome="abort", result=failed))
    task = nav.getAndTrackRoute(3, 7, use_start=True)
    sent = route_server.goals[-1]
    assert (sent.start_id, sent.goal_id, sent.use_poses, sent.use_start) == (3, 7, False, True)
    wait_done(nav, task)
    assert nav.getResult() is TaskResult.FAILED
    assert nav.getTaskError() == (405, sent_message(ComputeAndTrackRoute, "no way"))

    # A mixed pair is a failed request (upstream's answer), sent to nobody.
    before = len(route_server.goals)
    assert nav.getAndTrackRoute(3, pose(1.0, 1.0)) is None
    assert nav.getTaskError() == (ComputeAndTrackRoute.Result.UNKNOWN, "Request type fields were invalid!")
    assert nav.getAndTrackRoute(True, 2) is None  # a bool is not a node id
    with pytest.raises(ValueError, match="uint16"):
        nav.getAndTrackRoute(70000, 1)
    with pytest.raises(ValueError, match="finite"):
        nav.getAndTrackRoute(pose(0.0, 0.0), pose(float("nan"), 0.0))
    assert len(route_server.goals) == before

    route_server.scripts.append(Script(accept=False))
    assert nav.getAndTrackRoute(1, 2) is None
    assert nav.getTaskError() == (400, "Compute and track route was rejected!")
    assert nav.isTaskComplete(task=None)


def test_get_route_returns_path_and_route_or_none_with_the_error(fake: FakeNav2, nav: BasicNavigator) -> None:
    server = fake.action(ComputeRoute, "compute_route")
    route = Route(route_cost=4.5, nodes=[RouteNode(nodeid=1), RouteNode(nodeid=9)])
    server.scripts.append(Script(result=ComputeRoute.Result(path=path((0.0, 0.0), (3.0, 1.0)), route=route)))
    answer = nav.getRoute(pose(0.0, 0.0), pose(3.0, 1.0), use_start=True)
    assert answer is not None
    dense, sparse = answer
    assert isinstance(dense, Path) and len(dense.poses) == 2
    assert isinstance(sparse, Route) and [n.nodeid for n in sparse.nodes] == [1, 9] and sparse.route_cost == 4.5
    assert server.goals[-1].use_start and server.goals[-1].use_poses  # upstream dropped use_start
    assert nav.getTaskError() == (0, "")

    no_graph = result_with(ComputeRoute, error_code=402, error_msg="no graph")
    server.scripts.append(Script(outcome="abort", result=no_graph))
    assert nav.getRoute(1, 2) is None and nav.getTaskError() == (402, sent_message(ComputeRoute, "no graph"))
    server.scripts.append(Script(accept=False))
    assert nav.getRoute(1, 2) is None and nav.getTaskError() == (400, "Get route was rejected!")
    assert nav.getRoute(pose(0.0, 0.0), 2) is None and nav.getTaskError()[1] == "Request type fields were invalid!"
    # One-shot calls leave the main task's result alone.
    assert nav.getResult() is TaskResult.UNKNOWN and nav.isTaskComplete()


def geo(lat: float, lon: float, alt: float = 0.0) -> GeoPose:
    g = GeoPose()
    g.position.latitude, g.position.longitude, g.position.altitude = lat, lon, alt
    g.orientation.w = 1.0
    return g


def test_follow_gps_waypoints(fake: FakeNav2, nav: BasicNavigator) -> None:
    server = fake.action(FollowGPSWaypoints, "follow_gps_waypoints")
    feedback = [FollowGPSWaypoints.Feedback(current_waypoint=i) for i in range(3)]
    server.scripts.append(Script(feedback=feedback, feedback_period=0.2))
    waypoints = [geo(48.8584, 2.2945), geo(48.8606, 2.3376, float("nan")), geo(-33.8568, 151.2153)]
    task = nav.followGpsWaypoints(waypoints)
    assert task is RunningTask.FOLLOW_GPS_WAYPOINTS
    sent = server.goals[-1].gps_poses
    assert [round(g.position.latitude, 4) for g in sent] == [48.8584, 48.8606, -33.8568]
    assert math.isnan(sent[1].position.altitude)  # geographic_msgs' "no altitude" goes through
    current = set()
    deadline = time.monotonic() + 20
    while not nav.isTaskComplete(task=task):
        assert time.monotonic() < deadline
        f = nav.getFeedback(task=task)
        if f is not None:
            current.add(f.current_waypoint)
    assert nav.getResult() is TaskResult.SUCCEEDED and current and current <= {0, 1, 2}

    stop = FollowGPSWaypoints.Result(
        error_code=result_code(FollowGPSWaypoints, "STOP_ON_MISSED_WAYPOINT"), error_msg="missed"
    )
    server.scripts.append(Script(outcome="abort", result=stop))
    task = nav.followGpsWaypoints([geo(0.0, 0.0)], number_of_loops=2)
    assert server.goals[-1].number_of_loops == 2
    wait_done(nav, task)
    assert nav.getResult() is TaskResult.FAILED and nav.getTaskError() == (603, "missed")

    before = len(server.goals)
    for bad, match in (
        ([geo(91.0, 0.0)], "latitude"),
        ([geo(0.0, float("inf"))], "longitude"),
        ([geo(0.0, 0.0, float("inf"))], "altitude"),
        ([], "empty"),
        ([pose(0.0, 0.0)], "GeoPose"),
        (geo(0.0, 0.0), "list"),
    ):
        with pytest.raises((ValueError, TypeError), match=match):
            nav.followGpsWaypoints(bad)
    zero = geo(0.0, 0.0)
    zero.orientation.w = 0.0
    with pytest.raises(ValueError, match="quaternion"):
        nav.followGpsWaypoints([zero])
    assert len(server.goals) == before


def test_docking_server_by_id_and_by_pose(fake: FakeNav2, nav: BasicNavigator) -> None:
    dock = fake.action(DockRobot, "dock_robot")
    undock = fake.action(UndockRobot, "undock_robot")
    dock.scripts.append(Script(result=DockRobot.Result(success=True, num_retries=1)))
    task = nav.dockRobotByID("home", nav_to_dock=False)
    assert task is RunningTask.DOCK_ROBOT
    sent = dock.goals[-1]
    assert (sent.use_dock_id, sent.dock_id, sent.navigate_to_staging_pose) == (True, "home", False)
    wait_done(nav, task)
    assert nav.getResult() is TaskResult.SUCCEEDED

    not_found = DockRobot.Result(success=False, error_code=DockRobot.Result.DOCK_NOT_IN_DB, error_msg="no 'attic'")
    dock.scripts.append(Script(outcome="abort", result=not_found))
    wait_done(nav, nav.dockRobotByID("attic"))
    assert nav.getResult() is TaskResult.FAILED and nav.getTaskError() == (901, "no 'attic'")

    task = nav.dockRobotByPose(pose(1.5, -0.5, math.pi), dock_type="charging_dock")
    sent = dock.goals[-1]
    assert not sent.use_dock_id and sent.dock_type == "charging_dock" and sent.navigate_to_staging_pose
    assert sent.dock_pose.pose.position.x == 1.5 and sent.dock_pose.header.frame_id == "map"
    wait_done(nav, task)

    undock.scripts.append(Script(accept=False))
    assert nav.undockRobot("charging_dock") is None
    assert nav.getTaskError() == (999, "UndockRobot request was rejected!")
    assert undock.goals[-1].dock_type == "charging_dock"
    with pytest.raises(ValueError, match="dock_id"):
        nav.dockRobotByID("")
    with pytest.raises(TypeError, match="dock_pose"):
        nav.dockRobotByPose([1.0, 2.0])  # type: ignore[arg-type]


def test_a_goal_response_that_never_comes_times_out(fake: FakeNav2, nav: BasicNavigator) -> None:
    server = fake.action(NavigateToPose, "navigate_to_pose")
    server.scripts.append(Script(accept_delay=FAST.response + 2.0))
    start = time.monotonic()
    with pytest.raises(NavigatorTimeout, match="accept or reject"):
        nav.goToPose(pose(1.0, 1.0))
    assert time.monotonic() - start < FAST.response + 1.5  # bounded by the limit (a wide margin, not a speed)


def test_a_goal_accepted_after_its_response_timed_out_is_canceled(fake: FakeNav2, nav: BasicNavigator) -> None:
    """The navigator gave up waiting for the goal response, but the server accepts the goal later all the same. The
    cancel sent by the goal's id at the timeout finds no such goal yet; once the late acceptance is in, the navigator
    cancels the goal through its handle: no goal runs on unwatched."""
    server = fake.action(NavigateToPose, "navigate_to_pose")
    server.scripts.append(Script(accept_delay=FAST.response + 1.0, outcome="hold"))
    with pytest.raises(NavigatorTimeout, match="its cancel was sent"):
        nav.goToPose(pose(1.0, 1.0))
    assert server.canceled.wait(15.0), "the goal accepted after the timeout was never canceled"


def test_a_signals_cancel_goes_out_while_the_interrupted_thread_holds_the_clients_lock(
    fake: FakeNav2, nav: BasicNavigator
) -> None:
    """A signal's handler runs in the main thread wherever the signal found it, possibly inside send_goal_async
    with the action client's lock held, and waits a bounded time for its helper thread to send the cancels
    (_signals): the helper must not wait for that lock."""
    server = fake.action(NavigateToPose, "navigate_to_pose")
    server.scripts.append(Script(outcome="hold"))
    assert nav.goToPose(pose(1.0, 1.0))
    sent: list[Any] = []
    helper = threading.Thread(target=lambda: sent.extend(nav._tasks.send_cancels()), daemon=True)
    with nav._tasks.client("navigate_to_pose")._lock:  # held as by the main thread inside send_goal_async
        helper.start()
        helper.join(2.0)
        assert not helper.is_alive(), "send_cancels waited for the lock the interrupted thread holds"
    assert [name for name, _future in sent] == ["navigate_to_pose"]
    assert server.canceled.wait(10.0), "the cancel never reached the server"


def test_task_arguments_are_checked(nav: BasicNavigator) -> None:
    with pytest.raises(TypeError, match="RunningTask"):
        nav.isTaskComplete(task="navigate")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="RunningTask"):
        nav.getFeedback(task=3)  # type: ignore[arg-type]
    assert nav.isTaskComplete(task=RunningTask.NAVIGATE_TO_POSE)  # nothing runs
    assert nav.getFeedback(task=RunningTask.COMPUTE_AND_TRACK_ROUTE) is None
    nav.setTaskError(42, "mine")
    assert nav.getTaskError() == (42, "mine") and nav.last_action_error_code == 42
    nav.clearTaskError()
    assert nav.getTaskError() == (0, "")
    with pytest.raises(TypeError):
        nav.setTaskError("42", "x")  # type: ignore[arg-type]


def test_cancel_task_ends_the_main_task_and_the_route_together(fake: FakeNav2, nav: BasicNavigator) -> None:
    route_server = fake.action(ComputeAndTrackRoute, "compute_and_track_route")
    follow = fake.action(FollowPath, "follow_path")
    route_server.scripts.append(Script(outcome="hold"))
    follow.scripts.append(Script(outcome="hold", feedback=[FollowPath.Feedback(distance_to_goal=3.0)]))
    route_task = nav.getAndTrackRoute(1, 2)
    follow_task = nav.followPath(path((0.0, 0.0), (1.0, 0.0)))
    assert not nav.isTaskComplete(task=route_task) and not nav.isTaskComplete(task=follow_task)
    # The main task's feedback never leaks into the route's queue, nor the other way round.
    deadline = time.monotonic() + 10
    while nav.getFeedback(task=follow_task) is None:
        assert time.monotonic() < deadline
        time.sleep(0.02)
    assert nav.getFeedback(task=route_task) is None
    nav.cancelTask()
    wait_done(nav, follow_task)
    assert nav.getResult() is TaskResult.CANCELED
    wait_done(nav, route_task)
    assert nav.getResult() is TaskResult.CANCELED and route_server.canceled.is_set() and follow.canceled.is_set()
    nav.cancelTask()  # nothing runs: harmless


def test_a_new_route_replaces_the_old_one_and_its_unread_feedback(fake: FakeNav2, nav: BasicNavigator) -> None:
    route_server = fake.action(ComputeAndTrackRoute, "compute_and_track_route")
    road = path((0.0, 0.0), (1.0, 0.0))
    route_server.scripts.append(Script(feedback=[route_feedback(i, i + 1, False, road) for i in range(3)]))
    first = nav.getAndTrackRoute(1, 5)
    wait_done(nav, first)  # finished with three feedback messages nobody read
    route_server.scripts.append(Script(feedback=[route_feedback(7, 8, True, road)], outcome="abort"))
    second = nav.getAndTrackRoute(7, 9)
    wait_done(nav, second)
    got = []
    while (f := nav.getFeedback(task=second)) is not None:
        got.append(f.last_node_id)
    assert got == [7]  # only the new route's feedback, complete
    assert nav.getResult() is TaskResult.FAILED


def test_go_through_poses_takes_goals_or_a_list(fake: FakeNav2, nav: BasicNavigator) -> None:
    from nav2_msgs.action import NavigateThroughPoses
    from nav_msgs.msg import Goals

    server = fake.action(NavigateThroughPoses, "navigate_through_poses")
    goals = Goals()
    goals.header.frame_id = "map"
    goals.header.stamp.sec = 42
    goals.goals = [pose(1.0, 0.0), pose(2.0, 1.0)]
    wait_done(nav, nav.goThroughPoses(goals))  # Kilted's type: a nav_msgs/Goals
    sent = server.goals[-1]
    assert [g.pose.position.x for g in get_poses(sent, "poses")] == [1.0, 2.0]
    if wire_format() == "kilted":  # its header is kept; Jazzy's PoseStamped[] has no header of its own
        assert sent.poses.header.stamp.sec == 42
    wait_done(nav, nav.goThroughPoses([pose(3.0, 0.0)], behavior_tree="bt.xml"))  # Jazzy's type: a list
    sent = server.goals[-1]
    assert [g.pose.position.x for g in get_poses(sent, "poses")] == [3.0] and sent.behavior_tree == "bt.xml"
    if wire_format() == "kilted":  # the list gets a Goals header from its first pose
        assert sent.poses.header.frame_id == "map"
    assert nav.getResult() is TaskResult.SUCCEEDED
    for bad in (Goals(), [], [pose(float("inf"), 0.0)], "poses", [None]):
        with pytest.raises((TypeError, ValueError)):
            nav.goThroughPoses(bad)  # type: ignore[arg-type]


def test_a_missing_server_and_a_result_that_never_comes_time_out(fake: FakeNav2, nav: BasicNavigator) -> None:
    nav.timeouts = FAST.with_(server=1.0, result=2.0)
    # the graph's view of the server goes with the error: here, nothing of it at all
    nothing = "send_goal: 0 request readers, 0 reply writers; cancel_goal: 0 request readers"
    with pytest.raises(NavigatorTimeout, match=f"no action server 'follow_gps_waypoints'.*the graph shows {nothing}"):
        nav.followGpsWaypoints([geo(1.0, 2.0)])
    assert nav.isTaskComplete() and nav.getResult() is TaskResult.UNKNOWN

    server = fake.action(ComputeRoute, "compute_route")
    server.scripts.append(Script(outcome="hold"))
    with pytest.raises(NavigatorTimeout, match="result of the 'compute_route' goal"):
        nav.getRoute(1, 2)
    assert len(server.goals) == 1
