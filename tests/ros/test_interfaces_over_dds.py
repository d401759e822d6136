"""Our built interface packages work over real DDS between two processes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
from irobot_create_msgs.action import Dock  # noqa: E402
from nav2_msgs.action import NavigateToPose  # noqa: E402

from tb4.ros.action_client import ActionClient  # noqa: E402
from tb4.ros.future_waits import spin_until_future  # noqa: E402

PROGRAM = Path(__file__).parent / "programs" / "echo_action_server.py"


@pytest.fixture
def node():
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("interface_test_client", context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)


def _call(node, client: ActionClient, goal, feedback: list) -> object:
    assert client.wait_for_server(timeout_sec=20.0), "action server did not appear within 20 s"
    send = client.send_goal_async(goal, feedback_callback=lambda msg: feedback.append(msg.feedback))
    handle = spin_until_future(node, send, timeout=10.0, what="goal acceptance")
    assert handle.accepted
    return spin_until_future(node, handle.get_result_async(), timeout=10.0, what="result").result


def test_navigate_to_pose_and_dock_between_processes(start_process, node) -> None:
    server = start_process([sys.executable, str(PROGRAM)], name="echo")
    assert server.wait_for_output("echo server ready", timeout=20), server.output()

    nav = ActionClient(node, NavigateToPose, "navigate_to_pose")
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x = -13.0
    goal.pose.pose.position.y = 9.0
    feedback: list = []
    result = _call(node, nav, goal, feedback)
    assert result.error_code == NavigateToPose.Result.NONE
    assert result.error_msg == "reached -13.0,9.0"

    dock = ActionClient(node, Dock, "dock")
    dock_feedback: list = []
    dock_result = _call(node, dock, Dock.Goal(), dock_feedback)
    assert dock_result.is_docked is True
    assert server.alive()
