"""A navigator task whose action server went away ends FAILED within seconds, with a task error naming the server:
the simulator killed (SIGKILL) in the middle of goToPose (polled), followWaypoints, startToPose (blocking) and
undock; a server frozen (SIGSTOP), or killed and gone from the graph, mid-goal. A server that is quiet but healthy
is left alone.

Each test serves in a namespace of its own: a process killed hard stays in the ROS graph for its DDS lease (20 s),
and its endpoints must not stand in for another test's servers meanwhile."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from action_msgs.msg import GoalStatus, GoalStatusArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tb4.navigator import NavigatorTimeouts, TaskResult, TurtleBot4Directions
from tb4.processes import ManagedProcess, ros_environment

from .test_navigator_tasks import make_navigator, start_localized

D = TurtleBot4Directions
__all__ = ["make_navigator"]  # the fixture, imported for this module's tests

#: wall s from the kill to the task's end: the server_lost limit (5 s), the confirmation, and slack for a loaded
#: machine (the kill and the test's own polling)
FAILED_WITHIN = 10.0
SILENT_SERVER = Path(__file__).parent / "programs" / "silent_action_server.py"
READY, EXECUTING = "silent server ready", "silent server executing"  # what it prints (its READY and EXECUTING)
STATUS_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
FAR = ([-13.0, 9.0], D.EAST)  # a long drive from the dock of the warehouse


class Statuses:
    """Every status array an action server publishes (its status topic), newest last."""

    def __init__(self, ros: Any, action: str) -> None:
        """`action`: its full name (with the namespace)."""
        self.arrays: list[list[tuple[bytes, int]]] = []
        self.subscription = ros.node.create_subscription(
            GoalStatusArray, f"{action}/_action/status", self._on, STATUS_QOS
        )

    def _on(self, msg: GoalStatusArray) -> None:
        self.arrays.append([(bytes(s.goal_info.goal_id.uuid), int(s.status)) for s in msg.status_list])

    def seen(self, status: int) -> bool:
        return any(code == status for array in self.arrays for _goal, code in array)

    def wait_for(
        self, ros: Any, status: int, what: str, timeout: float = 30.0, while_running: ManagedProcess | None = None
    ) -> None:
        """Wait until some goal had `status`; fails at once if `while_running` (the process that should bring it
        about) ends first, with that process's output."""

        def found() -> bool | None:
            if self.seen(status):
                return True
            if while_running is not None and not while_running.alive():
                raise AssertionError(f"the process ended before {what}:\n{while_running.output()}")
            return None

        ros.wait_for(found, timeout=timeout, what=what)


def kill(process: ManagedProcess, sig: int = signal.SIGKILL) -> float:
    """Send `sig` to the process (by its id, while it is ours) and return the monotonic time it was sent."""
    assert process.alive()
    os.kill(process.pid, sig)
    return time.monotonic()


def poll_until_complete(nav: Any, since: float) -> float:
    """Poll isTaskComplete() as a user script does; returns the wall seconds from `since` to its True."""
    while not nav.isTaskComplete():
        assert time.monotonic() - since < FAILED_WITHIN + 20, "the task never ended"
    return time.monotonic() - since


def assert_lost(nav: Any, action: str, elapsed: float, how: str = "") -> None:
    assert nav.getResult() is TaskResult.FAILED, nav.getTaskError()
    code, message = nav.getTaskError()
    assert message.startswith(f"{action}: the action server"), message
    assert how in message and "while the goal was active" in message, message
    assert code != 0
    print(f"{action} ended FAILED {elapsed:.2f} s after the kill: {message}")
    assert elapsed < FAILED_WITHIN, f"{action} ended FAILED {elapsed:.1f} s after the kill ({message})"


def drive_until_feedback(nav: Any, what: str, timeout: float = 60.0) -> None:
    """Poll until the running task's feedback shows it under way."""
    deadline = time.monotonic() + timeout
    while nav.getFeedback() is None:
        assert not nav.isTaskComplete(), f"{what} ended before any feedback: {nav.getResult()} {nav.getTaskError()}"
        assert time.monotonic() < deadline, f"no feedback from {what}"


def test_go_to_pose_polled_fails_once_the_simulator_is_killed(start_simulator, make_navigator) -> None:
    # a few times real time: the drive lasts far longer than the test needs it to
    sim = start_simulator("--rate", "3", "--world", "warehouse", "--namespace", "lost_pose")
    nav = make_navigator(namespace="lost_pose")
    start_localized(nav)
    assert nav.goToPose(nav.getPoseStamped(*FAR))
    drive_until_feedback(nav, "navigate_to_pose")
    elapsed = poll_until_complete(nav, kill(sim))
    assert_lost(nav, "navigate_to_pose", elapsed)
    assert nav.getTaskStatusName() == "ABORTED"
    assert nav.isTaskComplete()  # and it stays so


def test_follow_waypoints_fails_once_the_simulator_is_killed(start_simulator, make_navigator) -> None:
    sim = start_simulator("--rate", "3", "--world", "warehouse", "--namespace", "lost_waypoints")
    nav = make_navigator(namespace="lost_waypoints")
    start_localized(nav)
    waypoints = [nav.getPoseStamped([-3.0, 0.0], D.EAST), nav.getPoseStamped(*FAR)]
    assert nav.followWaypoints(waypoints)
    drive_until_feedback(nav, "follow_waypoints")
    elapsed = poll_until_complete(nav, kill(sim))
    assert_lost(nav, "follow_waypoints", elapsed)


def run_blocking(call: Callable[[], Any]) -> tuple[threading.Thread, dict[str, Any]]:
    """Run `call` in a daemon thread (so that a hang fails the test instead of hanging it)."""
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["value"] = call()
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            box["error"] = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, box


def test_start_to_pose_returns_failed_once_the_simulator_is_killed(start_simulator, ros, make_navigator) -> None:
    statuses = Statuses(ros, "/lost_start/navigate_to_pose")
    sim = start_simulator("--rate", "3", "--world", "warehouse", "--namespace", "lost_start")
    nav = make_navigator(namespace="lost_start")
    start_localized(nav)
    thread, box = run_blocking(lambda: nav.startToPose(nav.getPoseStamped(*FAR)))
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the goal executing")
    killed = kill(sim)
    thread.join(FAILED_WITHIN + 20)
    assert not thread.is_alive(), "startToPose did not return"
    elapsed = time.monotonic() - killed
    assert "error" not in box, box
    assert box["value"] is TaskResult.FAILED
    assert_lost(nav, "navigate_to_pose", elapsed)


def test_undock_returns_false_once_the_simulator_is_killed(start_simulator, ros, make_navigator) -> None:
    statuses = Statuses(ros, "/lost_undock/undock")
    # real time: the Create 3's undocking (back off, turn about) lasts seconds
    sim = start_simulator("--rate", "1", "--world", "warehouse", "--namespace", "lost_undock")
    nav = make_navigator(namespace="lost_undock")
    assert nav.getDockedStatus() is True
    thread, box = run_blocking(nav.undock)
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the undock executing")
    killed = kill(sim)
    thread.join(FAILED_WITHIN + 20)
    assert not thread.is_alive(), "undock did not return"
    elapsed = time.monotonic() - killed
    assert box == {"value": False}, box
    code, message = nav.getTaskError()
    print(f"undock returned False {elapsed:.2f} s after the kill: {message}")
    assert message.startswith("undock: the action server") and code != 0, message
    assert elapsed < FAILED_WITHIN, f"undock returned {elapsed:.1f} s after the kill"


def start_silent_server(start_process, silent: float, namespace: str, **env: str) -> ManagedProcess:
    """The silent server (see its module) in `namespace`, with `env` added to the test session's ROS environment."""
    args = [sys.executable, str(SILENT_SERVER), str(silent), namespace]
    proc = start_process(args, name="silent_server", env={**ros_environment(int(os.environ["ROS_DOMAIN_ID"])), **env})
    assert proc.wait_for_output(READY, timeout=30), proc.output()
    return proc


#: a Fast DDS participant that other participants drop 1 s after its last announcement (the default: 20 s)
SHORT_LEASE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <participant profile_name="short_lease" is_default_profile="true">
      <rtps><builtin><discovery_config>
        <leaseDuration><sec>1</sec><nanosec>0</nanosec></leaseDuration>
        <leaseAnnouncement><sec>0</sec><nanosec>250000000</nanosec></leaseAnnouncement>
      </discovery_config></builtin></rtps>
    </participant>
  </profiles>
</dds>
"""


def test_a_quiet_healthy_server_is_not_taken_for_gone(start_process, make_navigator) -> None:
    """No feedback at all for three times the server_lost limit: the server still answers, so the goal runs on."""
    start_silent_server(start_process, silent=6.0, namespace="quiet")
    nav = make_navigator(namespace="quiet", timeouts=NavigatorTimeouts(server_lost=2.0, clock_discovery=0))
    started = time.monotonic()
    assert nav.goToPose(nav.getPoseStamped([1.0, 0.0], D.NORTH))
    while not nav.isTaskComplete():
        assert time.monotonic() - started < 40, "the goal never ended"
    assert nav.getResult() is TaskResult.SUCCEEDED, nav.getTaskError()
    assert nav.getTaskError() == (0, "")
    assert time.monotonic() - started >= 6.0


def test_a_frozen_server_fails_the_goal_by_its_silence(start_process, make_navigator) -> None:
    """Frozen (SIGSTOP): still in the graph, it answers nothing; after server_lost (2 s here) the goal is lost."""
    server = start_silent_server(start_process, silent=60.0, namespace="silent_frozen")
    nav = make_navigator(namespace="silent_frozen", timeouts=NavigatorTimeouts(server_lost=2.0, clock_discovery=0))
    assert nav.goToPose(nav.getPoseStamped([1.0, 0.0], D.NORTH))
    assert server.wait_for_output(EXECUTING, timeout=20), server.output()
    try:
        elapsed = poll_until_complete(nav, kill(server, signal.SIGSTOP))
    finally:
        os.kill(server.pid, signal.SIGCONT)  # so that the fixture's stop can end it
    assert_lost(nav, "navigate_to_pose", elapsed, "stopped answering")
    assert elapsed < 2.0 + 4.0


def test_a_server_that_left_the_graph_fails_the_goal_at_once(start_process, make_navigator, tmp_path) -> None:
    """Killed, with a DDS lease of 1 s: its node leaves the graph a second later, and the goal is lost on that sign
    alone (server_lost is far longer). With Fast DDS's default lease, 20 s, the silence tells first."""
    profile = tmp_path / "short_lease.xml"
    profile.write_text(SHORT_LEASE)
    server = start_silent_server(
        start_process, silent=60.0, namespace="silent_leaving", FASTDDS_DEFAULT_PROFILES_FILE=str(profile)
    )
    nav = make_navigator(namespace="silent_leaving", timeouts=NavigatorTimeouts(server_lost=60.0, clock_discovery=0))
    assert nav.goToPose(nav.getPoseStamped([1.0, 0.0], D.NORTH))
    assert server.wait_for_output(EXECUTING, timeout=20), server.output()
    elapsed = poll_until_complete(nav, kill(server))
    assert_lost(nav, "navigate_to_pose", elapsed, "went away (its node left the ROS graph)")
    assert elapsed < 1.0 + 4.0


def test_cancel_task_on_a_frozen_server_ends_the_goal_lost(start_process, make_navigator) -> None:
    """cancelTask() waits for the server's answer: a server that answers nothing no longer makes it wait out the
    whole response limit and raise; the goal ends lost instead."""
    server = start_silent_server(start_process, silent=60.0, namespace="silent_cancel")
    nav = make_navigator(namespace="silent_cancel", timeouts=NavigatorTimeouts(server_lost=2.0, clock_discovery=0))
    assert nav.goToPose(nav.getPoseStamped([1.0, 0.0], D.NORTH))
    assert server.wait_for_output(EXECUTING, timeout=20), server.output()
    frozen = kill(server, signal.SIGSTOP)
    try:
        nav.cancelTask()
        elapsed = time.monotonic() - frozen
    finally:
        os.kill(server.pid, signal.SIGCONT)
    assert nav.isTaskComplete()
    assert_lost(nav, "navigate_to_pose", elapsed, "stopped answering")
    assert elapsed < nav.timeouts.response
