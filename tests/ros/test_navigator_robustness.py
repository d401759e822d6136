"""Navigator robustness over DDS: no thread sees a half-built navigator, a request is asked a second time only
where that is safe (idempotent services), with the first request given the whole time limit, and an initial pose
counts as received only once the localizer reports it."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import FollowPath
from nav2_msgs.srv import ClearEntireCostmap, GetCostmap, ManageLifecycleNodes
from rclpy.action import ActionClient
from rclpy.duration import Duration

from tb4.core.geometry import same_pose
from tb4.core.waits import wait_until
from tb4.navigator import BasicNavigator, NavigatorTimeout, NavigatorTimeouts, TurtleBot4Navigator
from tb4.navigator.basic_navigator import AMCL_POSE_QOS
from tb4.ros.convert import pose_to_tuple

from .fake_nav2 import FakeNav2

LIMITS = NavigatorTimeouts(server=5.0, response=3.0, result=5.0, clock_discovery=0.0)


@pytest.fixture
def fake() -> Iterator[FakeNav2]:
    servers = FakeNav2()
    yield servers
    servers.close()


class _Observed(TurtleBot4Navigator):
    """A user's subclass that builds more clients after the TurtleBot 4 navigator's own __init__."""

    def __init__(self) -> None:
        super().__init__(timeouts=LIMITS)
        self.spinning_during_init = self._spinner.started
        self.extra = [ActionClient(self, FollowPath, f"extra_follow_{i}") for i in range(20)]
        self.spinning_after_clients = self._spinner.started


def test_spinning_starts_only_after_the_whole_construction(navigators: list[Any], capfd: pytest.CaptureFixture) -> None:
    for _ in range(5):
        nav = _Observed()
        navigators.append(nav)
        assert not nav.spinning_during_init and not nav.spinning_after_clients
        assert nav._spinner.started and nav._spinner._thread.is_alive()
    # Clients created while the executor runs are built with the executor kept out of the node.
    nav = navigators[-1]
    for i in range(20):
        nav._tasks.add(FollowPath, f"late_follow_{i}")
        time.sleep(0.005)
    time.sleep(0.3)
    # Fast DDS's own log lines aside: one read "Failed init_port fastdds_port7005: open_and_lock_file failed" in a
    # make test run (a shared-memory port another process held), and "_lock" is in it
    ours = [line for line in capfd.readouterr().err.splitlines() if "RTPS_" not in line]
    assert not [line for line in ours if "navigator executor" in line or "_lock" in line], ours


def test_a_request_from_inside_a_subclass_init_is_still_served(fake: FakeNav2, navigators: list[Any]) -> None:
    fake.service(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap")

    class ClearsFirst(BasicNavigator):
        def __init__(self) -> None:
            super().__init__(timeouts=LIMITS)
            self.clearLocalCostmap()  # needs the executor: it starts here, our part being built

    nav = ClearsFirst()
    navigators.append(nav)
    assert nav._spinner.started


def test_non_idempotent_requests_are_asked_once_with_the_whole_limit(fake: FakeNav2, navigators: list[Any]) -> None:
    def ok(_request: Any) -> ManageLifecycleNodes.Response:
        return ManageLifecycleNodes.Response(success=True)

    manager = fake.service(ManageLifecycleNodes, "lifecycle_manager_navigation/manage_nodes", ok)
    clear = fake.service(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap")
    nav = BasicNavigator(timeouts=LIMITS)
    navigators.append(nav)

    # Slower than half the limit: answered, and asked exactly once (a STARTUP is not sent twice).
    manager.delays = [0.7 * LIMITS.result]
    assert nav.lifecycleStartup() is True
    assert [r.command for r in manager.requests] == [ManageLifecycleNodes.Request.STARTUP]
    clear.delays = [0.7 * LIMITS.response]
    nav.clearLocalCostmap()
    assert len(clear.requests) == 1

    # Slower than the limit: a timeout, still one request; the error says what this side saw of the server
    manager.delays = [LIMITS.result + 2.0]
    seen = "1 request unanswered; the server is ready: yes; the graph shows 1 request reader, 1 reply writer"
    with pytest.raises(NavigatorTimeout, match=f"manage_nodes' \\({seen}\\)"):
        nav.lifecycleShutdown()
    time.sleep(2.5)  # past the slow answer: nothing else was sent meanwhile
    assert len(manager.requests) == 2


def test_idempotent_requests_are_asked_again_when_the_answer_is_late(fake: FakeNav2, navigators: list[Any]) -> None:
    def costmap(_request: Any) -> GetCostmap.Response:
        response = GetCostmap.Response()
        response.map.metadata.size_x, response.map.metadata.size_y = 7, 5
        response.map.data = [0] * 35
        return response

    service = fake.service(GetCostmap, "global_costmap/get_costmap", costmap)
    service.delays = [LIMITS.response + 2.0, 0.0]  # the first reply "lost" (too late), the second prompt
    nav = BasicNavigator(timeouts=LIMITS)
    navigators.append(nav)
    got = nav.getGlobalCostmap()
    assert (got.metadata.size_x, got.metadata.size_y) == (7, 5)
    assert len(service.requests) >= 2  # asked again each second without an answer (the second answers at once)

    service.requests.clear()
    service.delays = [0.0]
    nav.getGlobalCostmap()
    assert len(service.requests) == 1  # a prompt answer: no second request

    # No answer at all: every request the navigator sent is counted in the error
    service.delays = [LIMITS.response + 2.0] * 10
    with pytest.raises(NavigatorTimeout, match=r"get_costmap' \((3|4) requests unanswered; the server is ready: yes"):
        nav.getGlobalCostmap()
    # No server: the error says the graph shows none of it
    nav.timeouts = LIMITS.with_(server=1.0)
    missing = r"no service 'local_costmap/get_costmap' .*the graph shows 0 request readers, 0 reply writers"
    with pytest.raises(NavigatorTimeout, match=missing):
        nav.getLocalCostmap()


def test_an_action_client_still_being_built_is_invisible_to_the_executor(
    navigators: list[Any], capfd: pytest.CaptureFixture
) -> None:
    """The original failure: rclpy registers an ActionClient with its node before setting its _lock; an executor
    spinning the node meanwhile raised AttributeError. Here a client frozen in that state sits in the node while
    our executor spins: it is skipped, and nothing is logged."""
    nav = BasicNavigator(timeouts=LIMITS)
    navigators.append(nav)
    half_built = ActionClient.__new__(ActionClient)  # registered, nothing built yet: as rclpy leaves it mid-way
    nav.add_waitable(half_built)
    try:
        assert half_built not in list(nav.waitables)
        time.sleep(0.5)  # ten spins of the navigator's executor
        whole = ActionClient(nav, FollowPath, "whole_follow_path")
        assert whole in list(nav.waitables)
    finally:
        nav.remove_waitable(half_built)
    # Fast DDS's own log lines aside: one read "Failed init_port fastdds_port7005: open_and_lock_file failed" in a
    # make test run (a shared-memory port another process held), and "_lock" is in it
    ours = [line for line in capfd.readouterr().err.splitlines() if "RTPS_" not in line]
    assert not [line for line in ours if "navigator executor" in line or "_lock" in line], ours


def test_a_clock_discovered_late_is_followed_until_the_first_request(
    fake: FakeNav2, navigators: list[Any], ros
) -> None:
    """Automatic sim time: a /clock publisher discovered after the constructor's look (slow discovery on a loaded
    machine) is still followed, as long as no request was sent; after one, the clock stays what it was."""
    from rosgraph_msgs.msg import Clock

    from tb4.core.waits import wait_until

    fake.service(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap")
    looking = BasicNavigator("looking", timeouts=LIMITS.with_(clock_discovery=0.2))
    settled = BasicNavigator("settled", timeouts=LIMITS.with_(clock_discovery=0.2))
    navigators.extend([looking, settled])
    assert not looking.uses_sim_time and not settled.uses_sim_time  # no /clock in this domain yet
    settled.clearLocalCostmap()  # a request sent: its clock is settled (wall time)

    ros.node.create_publisher(Clock, "/clock", 10)  # lives as long as the client (destroyed with it)
    assert wait_until(lambda: looking.uses_sim_time, 20.0), "the late /clock was not followed"
    assert not settled.uses_sim_time


def test_docked_status_after_a_dock_waits_for_a_status_that_reflects_it(fake: FakeNav2, navigators: list[Any]) -> None:
    """A dock that succeeded, then statuses still saying "not docked" (sent before the robot docked and still
    queued at a starved client, or a robot whose status lags its dock action): getDockedStatus answers only once a
    status says what the dock's result said, within its limit."""
    import threading

    from irobot_create_msgs.action import Dock
    from irobot_create_msgs.msg import DockStatus
    from rclpy.qos import qos_profile_sensor_data

    docked = threading.Event()
    publisher = fake.node.create_publisher(DockStatus, "dock_status", qos_profile_sensor_data)
    stop = threading.Event()

    def publish_status() -> None:
        while not stop.is_set():
            publisher.publish(DockStatus(dock_visible=True, is_docked=docked.is_set()))
            time.sleep(0.02)

    def dock_then_status_later(_goal: Any) -> tuple[list[Any], Any]:
        threading.Timer(1.0, docked.set).start()  # the status says docked 1 s after the result
        return [], Dock.Result(is_docked=True)

    status_thread = threading.Thread(target=publish_status, daemon=True)
    status_thread.start()
    try:
        nav = TurtleBot4Navigator(timeouts=NavigatorTimeouts(server=5.0, response=3.0, result=5.0, dock_status=10.0))
        navigators.append(nav)
        server = fake.action(Dock, "dock")
        server.default.respond = dock_then_status_later
        assert nav.getDockedStatus() is False
        assert nav.dock() is True
        assert nav.getDockedStatus() is True  # not the "not docked" statuses sent in the second after the result
        assert docked.is_set()
    finally:
        stop.set()
        status_thread.join(timeout=2.0)


class FakeLocalizer:
    """amcl's side of the initial pose on a FakeNav2: amcl_pose latched with an estimate from before (the dock),
    delivered to every reader there is, lifecycle states 'active', and, once `listen()` is called, each initial pose
    taken and reported on amcl_pose as amcl does."""

    def __init__(self, fake: FakeNav2) -> None:
        self.fake = fake
        self.received: list[PoseWithCovarianceStamped] = []
        self.estimate = fake.node.create_publisher(PoseWithCovarianceStamped, "amcl_pose", AMCL_POSE_QOS)
        at_dock = PoseWithCovarianceStamped()
        at_dock.header.frame_id = "map"
        at_dock.pose.pose.orientation.w = 1.0
        self.estimate.publish(at_dock)
        assert wait_until(lambda: self.estimate.get_subscription_count() >= 1, 10.0), "nobody read amcl_pose"
        assert self.estimate.wait_for_all_acked(Duration(seconds=10)), "the latched estimate was never delivered"
        active = State(id=State.PRIMARY_STATE_ACTIVE, label="active")
        for node in ("amcl", "bt_navigator"):
            fake.service(GetState, f"{node}/get_state", lambda _request: GetState.Response(current_state=active))

    def listen(self) -> None:
        def on_initial_pose(msg: PoseWithCovarianceStamped) -> None:
            self.received.append(msg)
            self.estimate.publish(msg)  # as amcl: the new estimate is the pose given

        self.fake.node.create_subscription(PoseWithCovarianceStamped, "initialpose", on_initial_pose, 10)


def test_an_initial_pose_the_localizer_missed_is_sent_again_until_it_reports_it(
    fake: FakeNav2, navigators: list[Any]
) -> None:
    """The pose goes out before the localizer is up: a TurtleBot4Navigator's own reader of `initialpose` is no
    localizer, so nobody gets it. The localizer then comes up with its estimate from before latched on amcl_pose,
    and that estimate reaches the navigator first: it is not the pose set, so waitUntilNav2Active sends the pose
    again until amcl_pose reports it (upstream, and this navigator before, took the old estimate for an answer)."""
    nav = TurtleBot4Navigator(timeouts=LIMITS)
    navigators.append(nav)
    pose = nav.getPoseStamped([-2.0, 1.0], "EAST")
    nav.setInitialPose(pose)  # no localizer yet
    localizer = FakeLocalizer(fake)
    localizer.listen()

    nav.waitUntilNav2Active()
    assert localizer.received, "the localizer never got the initial pose"
    assert same_pose(pose_to_tuple(localizer.received[-1].pose.pose), pose_to_tuple(pose.pose))
    assert nav.initial_pose_received


def test_an_initial_pose_never_reported_times_out_naming_the_last_estimate(
    fake: FakeNav2, navigators: list[Any]
) -> None:
    nav = TurtleBot4Navigator(timeouts=LIMITS.with_(localization=2.0))
    navigators.append(nav)
    localizer = FakeLocalizer(fake)  # it never takes the pose
    nav.setInitialPose(nav.getPoseStamped([-2.0, 1.0], "EAST"))
    broken = PoseWithCovarianceStamped()  # a hostile estimate: NaN position, a zero quaternion
    broken.header.frame_id = "map"
    broken.pose.pose.position.x = broken.pose.pose.position.y = math.nan
    broken.pose.pose.orientation.w = 0.0  # the message's default is the identity (w = 1)
    localizer.estimate.publish(broken)
    assert localizer.estimate.wait_for_all_acked(Duration(seconds=10))
    said = r"no 'amcl_pose' at the initial pose \(-2.00, 1.00\) after 2 s \(the last was at \(nan, nan\)\)"
    with pytest.raises(NavigatorTimeout, match=said):
        nav.waitUntilNav2Active()
    assert not nav.initial_pose_received
