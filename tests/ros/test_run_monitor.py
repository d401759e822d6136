"""tb4 run's monitor keeps the state as each task began: at --rate max a whole task can begin and end between two
looks of the display, and its progress must still be shown (and reported in --json)."""

from __future__ import annotations

import io
import json

from action_msgs.msg import GoalStatus, GoalStatusArray
from nav2_msgs.action import NavigateToPose

from tb4.runner.display import Display
from tb4.runner.monitor import RunMonitor
from tb4.runner.session import _show_state


def status(*codes: int) -> GoalStatusArray:
    msg = GoalStatusArray()
    for i, code in enumerate(codes):
        entry = GoalStatus(status=code)
        entry.goal_info.goal_id.uuid[0] = i + 1
        msg.status_list.append(entry)
    return msg


def test_a_task_that_begins_and_ends_between_two_looks_is_still_reported() -> None:
    monitor = RunMonitor()
    try:
        out = io.StringIO()
        display = Display("json", out=out)
        _show_state(display, monitor)  # the display's first look: nothing has begun

        # between two looks: undock runs and ends, then a whole navigate_to_pose goal with its feedback
        monitor._on_status("undock", status(GoalStatus.STATUS_EXECUTING))
        monitor._on_status("undock", status(GoalStatus.STATUS_SUCCEEDED))
        feedback = NavigateToPose.Feedback()
        feedback.distance_remaining = 21.5
        monitor._on_feedback("navigate_to_pose", feedback)
        monitor._on_status("navigate_to_pose", status(GoalStatus.STATUS_EXECUTING))  # the task was already known
        monitor._on_status("navigate_to_pose", status(GoalStatus.STATUS_SUCCEEDED))
        assert monitor.state.snapshot()["task"] == "navigate_to_pose (succeeded)"

        _show_state(display, monitor)
        events = [json.loads(line) for line in out.getvalue().splitlines()]
        progress = [(e["task"], e.get("distance_remaining")) for e in events if e["event"] == "progress"]
        assert progress == [
            ("starting", None),
            ("undock", None),
            ("navigate_to_pose", 21.5),
            ("navigate_to_pose (succeeded)", 21.5),
        ]
        results = [(e["action"], e["status"]) for e in events if e["event"] == "result"]
        assert results == [("undock", "succeeded"), ("navigate_to_pose", "succeeded")]
        assert monitor.pop_task_starts() == []  # each start is shown once
    finally:
        monitor.close()


def test_waiting_for_action_servers_that_are_not_there_ends_at_its_timeout() -> None:
    monitor = RunMonitor()  # no simulator in this test's domain
    try:
        assert monitor.wait_for_publishers(0.2) is False
    finally:
        monitor.close()


def test_the_monitor_waits_for_the_bumper_as_for_the_action_servers() -> None:
    """At --rate max bump_and_go's bumps come within a wall second of its start: a monitor that had matched only
    the action servers when the tutorial began reported none of them live."""
    import importlib

    import rclpy
    from irobot_create_msgs.msg import HazardDetectionVector

    from tb4.ros.qos import LATCHED
    from tb4.runner.monitor import WATCHED_ACTIONS

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("stand_in_simulator", context=context)
    monitor = RunMonitor()
    try:
        for action, (package, name) in WATCHED_ACTIONS.items():
            action_type = getattr(importlib.import_module(f"{package}.action"), name)
            node.create_publisher(action_type.Impl.FeedbackMessage, f"{action}/_action/feedback", 10)
            node.create_publisher(GoalStatusArray, f"{action}/_action/status", LATCHED)  # rcl_action's QoS
        assert monitor.wait_for_publishers(2.0) is False  # every action server there, the bumper not yet
        node.create_publisher(HazardDetectionVector, "hazard_detection", 10)
        assert monitor.wait_for_publishers(20.0) is True
    finally:
        monitor.close()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def _finished_goal(sec: int, goal: int = 1) -> GoalStatusArray:
    """A status listing one succeeded goal, number `goal`, accepted at `sec` (the server's time)."""
    msg = status(GoalStatus.STATUS_SUCCEEDED)
    msg.status_list[0].goal_info.stamp.sec = sec
    msg.status_list[0].goal_info.goal_id.uuid[0] = goal
    return msg


def test_a_goal_the_monitor_learns_of_only_at_its_end_is_still_a_task_and_a_result() -> None:
    """The simulator's status writer can match the monitor after a whole goal is over (the monitor's own reader
    matched first, so the run had begun). rcl_action latches the status: the monitor reads it so, and reports
    the goal it missed live."""
    import rclpy

    from tb4.core.waits import wait_until
    from tb4.ros.qos import LATCHED

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("stand_in_simulator", context=context)
    monitor = None
    try:
        node.create_publisher(GoalStatusArray, "navigate_to_pose/_action/status", LATCHED).publish(_finished_goal(7))
        monitor = RunMonitor()  # only now: the goal ended before the monitor was there
        assert wait_until(lambda: monitor.events, 20.0), "the latched status never reached the monitor"
        assert monitor.pop_events() == [{"event": "result", "action": "navigate_to_pose", "status": "succeeded"}]
        assert [start["task"] for start in monitor.pop_task_starts()] == ["navigate_to_pose"]
        assert monitor.state.snapshot()["task"] == "navigate_to_pose (succeeded)"
    finally:
        if monitor is not None:
            monitor.close()
        node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_attached_to_a_running_simulator_its_earlier_goals_are_not_the_runs() -> None:
    from builtin_interfaces.msg import Time
    from rosgraph_msgs.msg import Clock

    monitor = RunMonitor()
    try:
        monitor._on_clock(Clock(clock=Time(sec=100)))
        monitor.mission_starts(attached=True)
        monitor._on_status("navigate_to_pose", _finished_goal(40))  # before the run: its latched status
        assert monitor.pop_events() == [] and monitor.pop_task_starts() == []
        monitor._on_status("navigate_to_pose", _finished_goal(130, goal=2))  # the run's own goal
        assert monitor.pop_events() == [{"event": "result", "action": "navigate_to_pose", "status": "succeeded"}]
    finally:
        monitor.close()
