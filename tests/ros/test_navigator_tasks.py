"""The navigator against the real simulator over DDS: every task method, each asserting what the robot did."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav2_msgs.action import FollowWaypoints, NavigateThroughPoses, NavigateToPose
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tb4.core.units import seconds_of
from tb4.navigator import (
    FootprintCollisionChecker,
    PyCostmap2D,
    TaskResult,
    TurtleBot4Directions,
    TurtleBot4Navigator,
)
from tb4.navigator.footprint_collision_checker import LETHAL_OBSTACLE, circle_footprint
from tb4.ros.convert import pose_to_tuple

D = TurtleBot4Directions
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture
def make_navigator() -> Iterator[Callable[..., TurtleBot4Navigator]]:
    """TurtleBot4Navigators in this process's default context, destroyed (and rclpy shut down) at teardown."""
    import rclpy

    if not rclpy.ok():
        rclpy.init()
    made: list[TurtleBot4Navigator] = []

    def make(**kwargs: Any) -> TurtleBot4Navigator:
        nav = TurtleBot4Navigator(**kwargs)
        made.append(nav)
        return nav

    yield make
    for nav in made:
        nav.destroyNode()
    rclpy.try_shutdown()


def start_localized(nav: TurtleBot4Navigator, undock: bool = True) -> None:
    """The tutorials' preamble: initial pose at the dock, wait for Nav2, undock."""
    nav.setInitialPose(nav.getPoseStamped([0.0, 0.0], D.NORTH))
    nav.waitUntilNav2Active()
    if undock:
        assert nav.undock()
        assert nav.getDockedStatus() is False


class FeedbackLog:
    """Every feedback message an action server sends (its feedback topic, deep queue): what the server reported,
    independent of when a polling script happens to look, which at --rate max on a loaded machine can be late."""

    def __init__(self, ros: Any, action_type: Any, name: str) -> None:
        """Subscribe before the simulator starts (see wait_matched)."""
        self.messages: list[Any] = []
        self.name = name
        self.subscription = ros.node.create_subscription(
            action_type.Impl.FeedbackMessage, f"{name}/_action/feedback", self._on, QoSProfile(depth=1000)
        )

    def wait_matched(self, ros: Any) -> None:
        """Wait (bounded) until this reader has matched the server's feedback writer.

        The writer must match the reader too, on the simulator's side, and only the reader's side can be seen
        from here: the feedback topic is volatile, so a reader the writer matches after the goal's drive (at
        --rate max, under load, the drive can take less time than that discovery) gets no feedback at all. A
        reader that exists before the simulator starts is announced in the simulator's first discovery exchange,
        seconds before any goal.
        """
        ros.wait_for(self.subscription.get_publisher_count, lambda n: n > 0, what=f"{self.name} feedback writer")

    def _on(self, msg: Any) -> None:
        self.messages.append(msg.feedback)

    def take(self, ros: Any, what: str, until: Callable[[list[Any]], bool] = bool) -> list[Any]:
        """The feedback received since the last take, once `until(received)` holds (waits, bounded; by default
        for at least one message: a goal's result can come in before its last feedback)."""
        ros.wait_for(lambda: list(self.messages), until, what=what)
        taken, self.messages = self.messages, []
        return taken


def run_to_end(nav: TurtleBot4Navigator, timeout: float = 120.0) -> list[Any]:
    """Poll like a user script; returns the feedback seen. Fails (not hangs) after `timeout`."""
    seen: list[Any] = []
    deadline = time.monotonic() + timeout
    while not nav.isTaskComplete():
        feedback = nav.getFeedback()
        if feedback is not None and (not seen or seen[-1] is not feedback):
            seen.append(feedback)
        assert time.monotonic() < deadline, "task did not finish"
    return seen


class Pose:
    """The robot's pose as amcl reports it (map frame)."""

    def __init__(self, ros: Any) -> None:
        self.ros = ros
        self.get = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)

    def now(self, timeout: float = 20.0) -> tuple[float, float, float]:
        """The pose once amcl_pose shows the robot at rest: two estimates in a row, stamped apart, that agree.
        One message is not enough: under load the test's spinner can still hold (or be about to hand over) one
        from the middle of a drive that ended a wall second ago (seen: 3 m short of a goal the robot reached).
        amcl_pose is republished every 0.5 sim-s, unchanged while the robot stands."""
        previous = self.ros.wait_for(self.get, what="amcl_pose")
        deadline = time.monotonic() + timeout
        while True:
            since = seconds_of(previous.header.stamp)
            current = self.ros.wait_for(
                self.get, lambda m, since=since: seconds_of(m.header.stamp) > since, what="a newer amcl_pose"
            )
            before, after = pose_to_tuple(previous.pose.pose), pose_to_tuple(current.pose.pose)
            moved = math.hypot(after[0] - before[0], after[1] - before[1])
            turned = abs(math.remainder(after[2] - before[2], 2 * math.pi))
            if moved < 0.01 and turned < 0.01:
                return after
            assert time.monotonic() < deadline, f"the robot was not at rest within {timeout} s (last {after})"
            previous = current

    def near(self, x: float, y: float, tol: float = 0.35) -> tuple[float, float, float]:
        pose = self.now()
        assert math.hypot(pose[0] - x, pose[1] - y) < tol, f"robot at {pose}, expected near ({x}, {y})"
        return pose


def test_navigation_tasks_move_the_robot(start_simulator, ros, make_navigator) -> None:
    # subscribed before the simulator starts: a reader the server matched late would miss a whole goal's feedback
    to_pose = FeedbackLog(ros, NavigateToPose, "navigate_to_pose")
    through = FeedbackLog(ros, NavigateThroughPoses, "navigate_through_poses")
    waypoints = FeedbackLog(ros, FollowWaypoints, "follow_waypoints")
    # Ten times real time, not max: each drive then lasts over a wall second, longer than the simulator can take
    # to match a feedback reader on a loaded machine (only the reader's side is seen here, see wait_matched); at
    # --rate max the first 3 m took tens of ms, and with three test workers per stage one run saw no feedback in
    # the navigator and another none in the log below.
    start_simulator("--rate", "10", "--world", "warehouse")
    nav = make_navigator()
    # every action client exists (discovered from the start), none is in the executor's wait set before its use
    assert action_clients_spun(nav) == set()
    pose = Pose(ros)
    for log in (to_pose, through, waypoints):
        log.wait_matched(ros)
    assert nav.getDockedStatus() is True  # the simulator is discovered (on a loaded machine, after the 1 s look)
    assert nav.uses_sim_time  # the simulator publishes /clock
    before = nav.get_clock().now().nanoseconds
    nav.sleep(3.0)  # simulated seconds
    assert nav.get_clock().now().nanoseconds - before >= 3e9
    start_localized(nav)

    assert nav.goToPose(nav.getPoseStamped([-3.0, 0.0], D.EAST))
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED and nav.getTaskError() == (0, "")
    assert nav.getFeedback() is not None  # the navigator surfaced the server's feedback
    sent = to_pose.take(ros, "navigate_to_pose feedback")
    assert sent[0].distance_remaining > 1.0  # from the start of the drive
    x, y, yaw = pose.near(-3.0, 0.0)
    assert abs(math.remainder(yaw - math.radians(270), 2 * math.pi)) < 0.3

    assert nav.goThroughPoses([nav.getPoseStamped([-3.0, -3.0], D.NORTH), nav.getPoseStamped([-1.0, -3.0], D.WEST)])
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    assert max(f.number_of_poses_remaining for f in through.take(ros, "through-poses feedback")) == 2
    pose.near(-1.0, -3.0)

    assert nav.followWaypoints([nav.getPoseStamped([-1.0, -1.0], D.WEST), nav.getPoseStamped([-1.0, 1.0], D.NORTH)])
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    last_is_1 = lambda fbs: bool(fbs) and fbs[-1].current_waypoint == 1  # noqa: E731
    waypoint_feedback = waypoints.take(ros, "the last waypoint's feedback", until=last_is_1)
    assert [f.current_waypoint for f in waypoint_feedback][0] == 0
    x0, y0, yaw0 = pose.near(-1.0, 1.0)

    assert nav.spin(1.57)
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    x1, y1, yaw1 = pose.now()
    assert abs(math.remainder(yaw1 - yaw0 - 1.57, 2 * math.pi)) < 0.2 and math.hypot(x1 - x0, y1 - y0) < 0.1

    assert nav.backup(0.3, 0.15)
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    x2, y2, _ = pose.now()
    heading = (math.cos(yaw1), math.sin(yaw1))
    assert (x2 - x1) * heading[0] + (y2 - y1) * heading[1] == pytest.approx(-0.3, abs=0.08)

    assert nav.driveOnHeading(0.3, 0.15)
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED
    x3, y3, _ = pose.now()
    assert (x3 - x2) * heading[0] + (y3 - y2) * heading[1] == pytest.approx(0.3, abs=0.08)

    started = time.monotonic()
    assert nav.assistedTeleop(time_allowance=1)
    run_to_end(nav)  # without teleop input it runs until the allowance ends: Nav2's TIMEOUT
    assert nav.getResult() is TaskResult.FAILED and nav.getTaskError()[0] == 731
    assert time.monotonic() - started < 30

    assert nav.startToPose(nav.getPoseStamped([0.8, 0.0], D.SOUTH)) is TaskResult.SUCCEEDED
    pose.near(0.8, 0.0)
    used = {"undock", "navigate_to_pose", "navigate_through_poses", "follow_waypoints", "spin", "backup"}
    used |= {"drive_on_heading", "assisted_teleop"}
    assert action_clients_spun(nav) == used
    unused = nav._tasks._clients["compute_route"]  # never used, yet found: it was discovered all along
    assert unused.server_is_ready()


def action_clients_spun(nav: TurtleBot4Navigator) -> set[str]:
    """The navigator's action clients that are in its node's waitables (what its executor waits on)."""
    waiting = {id(w) for w in nav.waitables}
    return {name for name, client in nav._tasks._clients.items() if id(client) in waiting}


def test_a_status_from_before_a_nav2_dock_does_not_answer_after_it(start_simulator, ros, make_navigator) -> None:
    """A dock_status sent while the robot was still approaching can come in after DockRobot's result (stress run
    s26: getDockedStatus answered False right after a successful dock). After a docking task that succeeded, the
    status must agree with it before it answers, as after the Create 3's Dock."""
    from irobot_create_msgs.msg import DockStatus

    start_simulator("--rate", "max", "--hold", "--world", "warehouse")
    nav = make_navigator()
    start_localized(nav)  # undocked
    assert nav.spin(math.pi)  # facing the dock
    run_to_end(nav)
    assert nav.dockRobotByID("home")
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED, nav.getTaskError()
    # As in the race: the result comes in, then a status queued during the approach. The spinner is kept out of
    # the node meanwhile, so that no genuine status comes in between (statuses sent after docking say True).
    with nav._spinner.paused():
        nav._tasks.on_finished(nav._tasks.main)  # the result, handled again
        nav._dockCallback(DockStatus(is_docked=False, dock_visible=True))  # the late one, from the approach
    assert nav.getDockedStatus() is True


def test_docking_through_nav2_and_create3(start_simulator, ros, make_navigator) -> None:
    start_simulator("--rate", "max", "--hold", "--world", "warehouse")
    nav = make_navigator()
    start_localized(nav, undock=False)

    assert nav.undockRobot()
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED and nav.getDockedStatus() is False

    assert nav.dockRobotByID("nope")  # accepted, then fails: no such dock
    run_to_end(nav)
    assert nav.getResult() is TaskResult.FAILED and nav.getTaskError()[0] == 901

    assert nav.spin(math.pi)  # undocking leaves the robot facing away from the dock: turn to see it
    run_to_end(nav)
    assert nav.dockRobotByID("home")
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED, nav.getTaskError()
    assert nav.getDockedStatus() is True

    assert nav.undock() and nav.getDockedStatus() is False
    assert nav.spin(math.pi)
    run_to_end(nav)
    dock_pose = nav.getPoseStamped([0.0, 0.0], D.NORTH)
    assert nav.dockRobotByPose(dock_pose, "")
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED and nav.getDockedStatus() is True
    assert nav.undock()
    assert nav.spin(math.pi)
    run_to_end(nav)
    assert nav.dock() is True and nav.getDockedStatus() is True


def test_paths_are_collision_free_and_followable(start_simulator, ros, make_navigator) -> None:
    start_simulator("--rate", "max", "--hold", "--world", "warehouse")
    nav = make_navigator()
    pose = Pose(ros)
    start_localized(nav)

    goal = nav.getPoseStamped([-3.0, -3.0], D.NORTH)
    path = nav.getPath(None, goal)
    assert path is not None and len(path.poses) > 5
    end = path.poses[-1].pose.position
    assert math.hypot(end.x + 3.0, end.y + 3.0) < 0.1

    checker = FootprintCollisionChecker()
    checker.setCostmap(PyCostmap2D(nav.getGlobalCostmap()))
    footprint = circle_footprint(0.175)
    costs = [checker.footprintCostAtPose(*pose_to_tuple(p.pose), footprint) for p in path.poses]
    assert max(costs) < LETHAL_OBSTACLE  # the robot's outline never touches an obstacle along the path

    through = nav.getPathThroughPoses(None, [nav.getPoseStamped([-3.0, 0.0], D.EAST), goal])
    assert through is not None
    assert min(math.hypot(p.pose.position.x + 3.0, p.pose.position.y) for p in through.poses) < 0.1

    start = nav.getPoseStamped([-3.0, 0.0], D.EAST)
    from_start = nav.getPath(start, goal, use_start=True)
    assert from_start is not None
    first = from_start.poses[0].pose.position
    assert math.hypot(first.x + 3.0, first.y) < 0.1

    smoothed = nav.smoothPath(path)
    assert smoothed is not None and len(smoothed.poses) >= 2
    last = smoothed.poses[-1].pose.position
    assert math.hypot(last.x + 3.0, last.y + 3.0) < 0.15

    assert nav.followPath(smoothed)
    run_to_end(nav)
    assert nav.getResult() is TaskResult.SUCCEEDED, nav.getTaskError()
    pose.near(-3.0, -3.0, tol=0.4)
