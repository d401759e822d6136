"""A goal the simulator cannot decide on is answered: rejected, with the reason in the simulator's log.

rclpy sends no goal response when the server's goal callback raises; the client then waits for an answer that never
comes (its own bound ends it, with nothing said on the server's side). The Create 3's dock and undock decide by
asking the simulation loop (is the robot docked, may it move), which a stalled loop answers with a TimeoutError.
"""

from __future__ import annotations

import time
from typing import Any

from nav2_msgs.action import Spin

from tb4.core.waits import wait_for_future

from .test_bridge_cancel import _EndlessTask, served


def test_a_goal_whose_decision_raises_is_rejected_not_left_unanswered(capfd) -> None:
    def stalled_loop(_goal: Any) -> bool:
        raise TimeoutError("the loop did not answer in 10 s")

    tasks: list[_EndlessTask] = []
    with served("bridge_accept", tasks, accept=stalled_loop) as client:
        sent = time.monotonic()
        handle = wait_for_future(client.send_goal_async(Spin.Goal()), 15.0, "the goal response")
        answered_in = time.monotonic() - sent
    assert not handle.accepted
    assert answered_in < 10.0
    assert tasks == []
    reason = "deciding on it failed (TimeoutError: the loop did not answer in 10 s)"
    assert f"bridge_accept goal rejected: {reason}" in capfd.readouterr().err
