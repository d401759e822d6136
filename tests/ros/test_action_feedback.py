"""The simulator's action feedback, sent on a writer of the server's own (tb4.ros.action_bridge), reaches a client
built the way third-party code builds one: rclpy's stock ActionClient with its default QoS, in a process that
sends its goal as soon as it finds the server. Its first feedback is there, and every message names its goal.

The server makes sure the client's feedback reader is there before its first message; it cannot make the client
read it. A client whose executor takes nothing for a while (starved on a loaded machine) loses the oldest messages
to its own queue (rclpy's default keeps the newest ten), and rclpy drops a goal's feedback still queued when the
result comes: on any server. So the first message may be missing only when the client's executor stalled."""

from __future__ import annotations

import time
from itertools import pairwise
from typing import Any

import pytest
from irobot_create_msgs.action import DriveDistance
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType

from tb4.core.waits import wait_for_future
from tb4.ros.action_bridge import FEEDBACK_PERIOD
from tb4.ros.background import BackgroundNode

from .create3_helpers import SUCCEEDED, lab_world

pytestmark = pytest.mark.dds

DISTANCE = 0.5  # m
TICK = 0.01  # s between the client executor's own timer callbacks, which show when it stalled
# a stall that long (five feedback periods, half what fills rclpy's default feedback queue) shows a starved client
STALL = 5 * FEEDBACK_PERIOD


def test_a_stock_rclpy_client_gets_its_goals_feedback_first_message_included(start_simulator, tmp_path) -> None:
    start_simulator("--rate", "4", "--world", lab_world(tmp_path), "--exact")
    side = BackgroundNode("stock_feedback_client")
    try:
        with side.paused():
            client = ActionClient(side.node, DriveDistance, "drive_distance")  # rclpy's, every QoS its default
        ticks: list[float] = []
        side.node.create_timer(
            TICK, lambda: ticks.append(time.monotonic()), clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        side.start()
        assert client.wait_for_server(timeout_sec=20.0), "no drive_distance server after 20 s"
        received: list[Any] = []
        goal = DriveDistance.Goal(distance=DISTANCE, max_translation_speed=0.2)
        sent_at = time.monotonic()
        handle = wait_for_future(
            client.send_goal_async(goal, feedback_callback=received.append), 10.0, "the goal's answer"
        )
        assert handle.accepted
        result = wait_for_future(handle.get_result_async(), 20.0, "the drive's result")
        assert result.status == SUCCEEDED
        during = [sent_at, *(t for t in ticks if t > sent_at), time.monotonic()]
        stall = max(later - earlier for earlier, later in pairwise(during))
        assert received, "no feedback at all"
        assert all(bytes(m.goal_id.uuid) == bytes(handle.goal_id.uuid) for m in received)
        remaining = [m.feedback.remaining_travel_distance for m in received]
        # the first message is the drive's start: (almost) all of its distance still to go
        if stall < STALL:
            assert remaining[0] > DISTANCE - 0.05, (
                f"{remaining[:5]}; the client's executor stalled {stall:.3f} s at most"
            )
        assert remaining == sorted(remaining, reverse=True), remaining
    finally:
        side.close()
