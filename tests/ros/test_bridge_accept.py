"""A goal the simulator cannot decide on is answered: rejected, with the reason in the simulator's log.

rclpy sends no goal response when the server's goal callback raises; the client then waits for an answer that never
comes (its own bound ends it, with nothing said on the server's side). The Create 3's dock and undock decide by
asking the simulation loop (is the robot docked, may it move), which a stalled loop answers with a TimeoutError.
"""

from __future__ import annotations

import time
from typing import Any

from nav2_msgs.action import Spin

from tb4.core.waits import wait_for_future, wait_until

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


REPORTED = "a bridge_slow goal: still deciding after 0.2 s; the threads:"


def test_a_slow_decision_is_reported_with_where_it_waits(monkeypatch, capfd) -> None:
    import tb4.ros.stall_report as stall_report

    monkeypatch.setattr(stall_report, "STALL_REPORT_AFTER", 0.2)

    decisions: list[Any] = []

    def slow_decision(goal: Any) -> bool:
        decisions.append(goal)
        if len(decisions) > 1:
            time.sleep(0.8)
        return True

    def goal_sent_and_canceled(client: Any) -> None:
        handle = wait_for_future(client.send_goal_async(Spin.Goal()), 15.0, "the goal response")
        assert handle.accepted
        wait_for_future(handle.cancel_goal_async(), 15.0, "the cancel response")
        wait_for_future(handle.get_result_async(), 15.0, "the canceled goal's result")  # ended while served

    tasks: list[_EndlessTask] = []
    with served("bridge_slow", tasks, accept=slow_decision) as client:
        # A first, quick goal: its answer came, so the server knows the client's reply reader, and the slow goal's
        # decision waits for nothing else (on a loaded machine the wait for a new client's reply reader took
        # longer than the report's delay, and the report showed that wait instead)
        goal_sent_and_canceled(client)
        capfd.readouterr()
        goal_sent_and_canceled(client)
        # The report comes from a timer thread: on a loaded machine its log line was written after the test had
        # returned (stress run 56: in the test's output, past its capture, with the decision's stack in it)
        logged: list[str] = []

        def reported() -> bool:
            logged.append(capfd.readouterr().err)
            return REPORTED in "".join(logged)

        wait_until(reported, 10.0)
    assert REPORTED in "".join(logged)
    assert "slow_decision: time.sleep(0.8)" in "".join(logged)


def test_the_queue_watch_reads_rclpys_own_multithreaded_executor() -> None:
    """ExecutorQueueWatch reads the queue of the thread pool inside rclpy's MultiThreadedExecutor (rclpy 7 and 9
    alike): the simulator's executor, not a stand-in, has to be watched."""
    import threading

    import rclpy
    from rclpy.executors import MultiThreadedExecutor

    from tb4.ros.stall_report import ExecutorQueueWatch

    context = rclpy.Context()
    rclpy.init(context=context)
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    release = threading.Event()
    said: list[str] = []
    try:
        watch = ExecutorQueueWatch(executor, said.append, after=1.0)
        for _ in range(2):  # both its threads busy, as with stuck callbacks
            executor._executor.submit(release.wait, 10.0)
        executor._executor.submit(lambda: None)
        time.sleep(0.1)
        watch.look(now=10.0)
        watch.look(now=11.5)
        assert len(said) == 1 and said[0].startswith("1 callback(s) have waited 1.5 s for a free executor thread")
    finally:
        release.set()
        executor.shutdown(timeout_sec=5.0)
        rclpy.try_shutdown(context=context)
