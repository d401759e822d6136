"""Every request of a burst gets its answer: goals and service calls sent back to back to a real simulator by a
client that takes nothing meanwhile (its executor busy, as a script's can be) each get their reply once it spins.

DDS keeps at most a reader's QoS depth of samples not yet taken and overwrites the oldest; rclpy takes one request
or reply per executor wake-up. With rclpy's default depth of 10 the simulator lost most requests of such a burst
and the client most replies; the client then waited for a goal response that could never come. Every request and
reply queue of ours is deep (tb4.ros.qos.REQUESTS)."""

from __future__ import annotations

import time
from typing import Any

from action_msgs.srv import CancelGoal
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import NavigateToPose

from tb4.core.waits import wait_until

BURST = 100  # requests sent back to back: ten times rclpy's default queue depth
HOLD = 1.0  # s the client takes nothing after sending them, while the simulator answers
ANSWER_WAIT = 15.0  # s for every answer once the client spins again


def burst(ros: Any, send: Any) -> list[Any]:
    """Send BURST requests with the client's executor held (HOLD s more), then wait for the answers (bounded)."""
    with ros.paused():
        futures = [send() for _ in range(BURST)]
        time.sleep(HOLD)
    wait_until(lambda: all(f.done() for f in futures), ANSWER_WAIT)
    return futures


def test_every_goal_of_a_burst_gets_its_response(start_simulator, ros) -> None:
    start_simulator("--world", "warehouse")
    client = ros.action_client(NavigateToPose, "navigate_to_pose")
    assert client.wait_for_server(timeout_sec=20.0)
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x = -1.0
    goal.pose.pose.orientation.w = 1.0
    futures = burst(ros, lambda: client.send_goal_async(goal))
    answered = [f for f in futures if f.done()]
    try:
        assert len(answered) == BURST, f"{BURST - len(answered)} of {BURST} goals got no goal response"
        assert all(f.exception() is None for f in answered)
        # each goal preempts the one before it: the last one accepted runs on
        assert futures[-1].result().accepted
    finally:  # cancel every goal (a zero id and stamp name them all)
        ros.service(CancelGoal, "navigate_to_pose/_action/cancel_goal", CancelGoal.Request())


def test_every_call_of_a_burst_gets_its_reply(start_simulator, ros) -> None:
    start_simulator("--world", "warehouse")
    client = ros.service_client(GetState, "bt_navigator/get_state")
    futures = burst(ros, lambda: client.call_async(GetState.Request()))
    answered = [f for f in futures if f.done()]
    assert len(answered) == BURST, f"{BURST - len(answered)} of {BURST} get_state calls got no reply"
    assert {f.result().current_state.label for f in answered} == {"active"}
