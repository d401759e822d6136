"""The simulator's action feedback, sent on a writer of the server's own (tb4.ros.action_bridge), reaches a client
built the way third-party code builds one: rclpy's stock ActionClient with its default QoS, in a process that
sends its goal as soon as it finds the server. Its first feedback is there, and every message names its goal."""

from __future__ import annotations

from typing import Any

import pytest
from irobot_create_msgs.action import DriveDistance
from rclpy.action import ActionClient

from tb4.core.waits import wait_for_future
from tb4.ros.background import BackgroundNode

from .create3_helpers import SUCCEEDED, lab_world

pytestmark = pytest.mark.dds

DISTANCE = 0.5  # m


def test_a_stock_rclpy_client_gets_its_goals_feedback_first_message_included(start_simulator, tmp_path) -> None:
    start_simulator("--rate", "4", "--world", lab_world(tmp_path), "--exact")
    side = BackgroundNode("stock_feedback_client")
    try:
        with side.paused():
            client = ActionClient(side.node, DriveDistance, "drive_distance")  # rclpy's, every QoS its default
        side.start()
        assert client.wait_for_server(timeout_sec=20.0), "no drive_distance server after 20 s"
        received: list[Any] = []
        goal = DriveDistance.Goal(distance=DISTANCE, max_translation_speed=0.2)
        handle = wait_for_future(
            client.send_goal_async(goal, feedback_callback=received.append), 10.0, "the goal's answer"
        )
        assert handle.accepted
        result = wait_for_future(handle.get_result_async(), 20.0, "the drive's result")
        assert result.status == SUCCEEDED
        assert received, "no feedback at all"
        assert all(bytes(m.goal_id.uuid) == bytes(handle.goal_id.uuid) for m in received)
        remaining = [m.feedback.remaining_travel_distance for m in received]
        # the first message is the drive's start: (almost) all of its distance still to go
        assert remaining[0] > DISTANCE - 0.05, remaining[:5]
        assert remaining == sorted(remaining, reverse=True), remaining
    finally:
        side.close()
