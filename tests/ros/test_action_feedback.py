"""The simulator's action feedback, sent on a writer of the server's own (tb4.ros.action_bridge), reaches a client
built the way third-party code builds one: rclpy's stock ActionClient with its default QoS, in a process that
sends its goal as soon as it finds the server. Its first feedback is there, and every message names its goal.

The server makes sure the client's feedback reader is there before its first message, and slows its next ones
until the first is acknowledged; it cannot make the client read it, and a reader that never acknowledges (a dead or
stopped process) does not stop another client's feedback. A client whose executor takes nothing for a
while (starved on a loaded machine) loses the oldest messages to its own queue (rclpy's default keeps the newest
ten), and rclpy drops a goal's feedback still queued when the result comes: on any server. So the first message
may be missing only when the client's executor stalled."""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
from irobot_create_msgs.action import DriveDistance
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType

from tb4.core.waits import wait_for_future, wait_until
from tb4.ros.action_bridge import FEEDBACK_PERIOD
from tb4.ros.background import BackgroundNode

from .create3_helpers import SUCCEEDED, lab_world

pytestmark = pytest.mark.dds

DISTANCE = 0.5  # m
TICK = 0.01  # s between the client executor's own timer callbacks, which show when it stalled
# a stall that long (five feedback periods, half what fills rclpy's default feedback queue) shows a starved client
STALL = 5 * FEEDBACK_PERIOD
# s between two feedback messages at most: until the first is acknowledged (with the writer's next heartbeat, every
# 0.1 s with the simulator's DDS profile) the next ones come every HELD_FEEDBACK_PERIOD
HELD_AT_MOST = 1.0


@dataclass
class Drive:
    """A drive's feedback as a stock client received it: the messages, when each arrived (monotonic s), and the
    longest its executor went without running a callback while the goal ran (s)."""

    received: list[Any]
    arrivals: list[float]
    stall: float

    @property
    def remaining(self) -> list[float]:
        return [m.feedback.remaining_travel_distance for m in self.received]


def _drive_with_a_stock_client(distance: float) -> Drive:
    """Drive `distance` through rclpy's stock ActionClient (every QoS its default) on a node spun in the background;
    asserts the drive succeeded and that every feedback message named its goal."""
    side = BackgroundNode("stock_feedback_client")
    try:
        with side.paused():
            client = ActionClient(side.node, DriveDistance, "drive_distance")
        ticks: list[float] = []
        side.node.create_timer(
            TICK, lambda: ticks.append(time.monotonic()), clock=Clock(clock_type=ClockType.STEADY_TIME)
        )
        side.start()
        assert client.wait_for_server(timeout_sec=20.0), "no drive_distance server after 20 s"
        received: list[Any] = []
        arrivals: list[float] = []

        def feedback(message: Any) -> None:
            received.append(message)
            arrivals.append(time.monotonic())

        goal = DriveDistance.Goal(distance=distance, max_translation_speed=0.2)
        sent_at = time.monotonic()
        handle = wait_for_future(client.send_goal_async(goal, feedback_callback=feedback), 10.0, "the goal's answer")
        assert handle.accepted
        result = wait_for_future(handle.get_result_async(), 20.0, "the drive's result")
        assert result.status == SUCCEEDED
        during = [sent_at, *(t for t in ticks if t > sent_at), time.monotonic()]
        assert all(bytes(m.goal_id.uuid) == bytes(handle.goal_id.uuid) for m in received)
        return Drive(received, arrivals, max(later - earlier for earlier, later in pairwise(during)))
    finally:
        side.close()


def test_a_stock_rclpy_client_gets_its_goals_feedback_first_message_included(start_simulator, tmp_path) -> None:
    start_simulator("--rate", "4", "--world", lab_world(tmp_path), "--exact")
    drive = _drive_with_a_stock_client(DISTANCE)
    remaining = drive.remaining
    assert remaining, "no feedback at all"
    # the first message is the drive's start: (almost) all of its distance still to go
    if drive.stall < STALL:
        assert remaining[0] > DISTANCE - 0.05, (
            f"{remaining[:5]}; the client's executor stalled {drive.stall:.3f} s at most"
        )
        arrivals = drive.arrivals
        assert len(arrivals) > 1 and arrivals[1] - arrivals[0] < HELD_AT_MOST, (remaining, arrivals[:3])
    assert remaining == sorted(remaining, reverse=True), remaining


LURKER = """
import os, signal, rclpy
from irobot_create_msgs.action import DriveDistance
from rclpy.action import ActionClient

rclpy.init()
node = rclpy.create_node("lurking_feedback_reader")
client = ActionClient(node, DriveDistance, "drive_distance")
assert client.wait_for_server(timeout_sec=20.0), "no drive_distance server"
print("stopping", flush=True)
os.kill(os.getpid(), signal.SIGSTOP)  # its feedback reader stays matched and acknowledges nothing from now on
"""


def test_a_reader_that_never_acknowledges_does_not_hold_another_clients_feedback(
    start_simulator, start_process, tmp_path
) -> None:
    """A process that died without a word stays in Fast DDS's graph, its readers matched, for its lease (20 s), and
    a stopped one for as long as it is stopped: the server's feedback writer then never has all it sent
    acknowledged. Another client's goal still gets its feedback every HELD_FEEDBACK_PERIOD or so; it used to get its
    first message and, for a goal shorter than the 2 s bound, nothing more."""
    start_simulator("--rate", "4", "--world", lab_world(tmp_path), "--exact")
    lurker = start_process([sys.executable, "-c", LURKER], name="lurker")
    assert lurker.wait_for_output("stopping", timeout=30), lurker.output()
    assert wait_until(lambda: _state(lurker.popen.pid) == "T", 5.0), "the lurker did not stop"
    try:
        drive = _drive_with_a_stock_client(2 * DISTANCE)  # 5 s of sim time: 1.25 s at --rate 4
    finally:
        os.kill(lurker.popen.pid, signal.SIGCONT)  # so that the fixture's stop can end it
    assert drive.received, "no feedback at all"
    if drive.stall < STALL:
        gaps = [later - earlier for earlier, later in pairwise(drive.arrivals)]
        assert len(drive.arrivals) >= 3 and max(gaps) < HELD_AT_MOST, (drive.remaining, gaps)


FROZEN_CLIENT = """
import json, os, signal, rclpy
from irobot_create_msgs.action import DriveDistance
from rclpy.action import ActionClient

rclpy.init()
node = rclpy.create_node("frozen_feedback_client")
client = ActionClient(node, DriveDistance, "drive_distance")
assert client.wait_for_server(timeout_sec=20.0), "no drive_distance server"
remaining = []
goal = DriveDistance.Goal(distance=%r, max_translation_speed=0.2)
sent = client.send_goal_async(goal, feedback_callback=lambda m: remaining.append(m.feedback.remaining_travel_distance))
print("freezing", flush=True)
os.kill(os.getpid(), signal.SIGSTOP)  # the whole process, Fast DDS's threads included: nothing read, nothing acked
rclpy.spin_until_future_complete(node, sent, timeout_sec=10.0)
done = sent.result().get_result_async()
rclpy.spin_until_future_complete(node, done, timeout_sec=20.0)
print(json.dumps({"status": done.result().status, "remaining": remaining}), flush=True)
"""
FROZEN_FOR = 0.7  # s: at --rate 4 the drive sends 14 messages meanwhile, more than a default reader keeps


def test_a_client_that_reads_late_still_gets_the_first_feedback(start_simulator, start_process, tmp_path) -> None:
    """The client's side of a match can come later than the server's (a loaded machine): it then gets only what the
    server's writer still holds when it comes. Here the client stops (SIGSTOP) right after sending its goal, so
    that it acknowledges nothing until it resumes; the server slows its next feedback until the first is
    acknowledged (a bound of REPLY_READER_WAIT), so the first message is still there."""
    start_simulator("--rate", "4", "--world", lab_world(tmp_path), "--exact")
    client = start_process([sys.executable, "-c", FROZEN_CLIENT % DISTANCE], name="frozen_client")
    assert client.wait_for_output("freezing", timeout=30), client.output()
    assert wait_until(lambda: _state(client.popen.pid) == "T", 5.0), "the client did not stop"
    time.sleep(FROZEN_FOR)
    os.kill(client.popen.pid, signal.SIGCONT)
    assert client.popen.wait(40) == 0, client.output()
    report = json.loads(next(line for line in reversed(client.output().splitlines()) if line.startswith("{")))
    assert report["status"] == SUCCEEDED
    assert report["remaining"], "no feedback at all"
    assert report["remaining"][0] > DISTANCE - 0.05, report["remaining"][:5]


def _state(pid: int) -> str:
    """A process's state letter from /proc (T: stopped)."""
    stat = Path(f"/proc/{pid}/stat").read_text()
    return stat[stat.rindex(")") + 2]
