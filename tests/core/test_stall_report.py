"""The simulator's stall reports: a slow goal decision and callbacks waiting for an executor thread are said with
every thread's stack; a quick decision and a queue that drains say nothing."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

from tb4.ros.stall_report import ExecutorQueueWatch, SlowDecisionReport, thread_stacks


def _park(until: threading.Event) -> None:
    until.wait(10.0)


def test_thread_stacks_name_each_thread_and_where_it_waits() -> None:
    release = threading.Event()
    parked = threading.Thread(target=_park, args=(release,), name="parked-thread")
    parked.start()
    try:
        stacks = thread_stacks()
    finally:
        release.set()
        parked.join(5.0)
    assert "thread parked-thread:" in stacks
    assert " _park: until.wait(10.0)" in stacks


def test_a_decision_still_running_is_reported_once_and_a_quick_one_not_at_all() -> None:
    said: list[str] = []
    with SlowDecisionReport("a dock goal", said.append, after=0.05):
        pass
    time.sleep(0.2)
    assert said == []
    with SlowDecisionReport("a dock goal", said.append, after=0.05):
        time.sleep(0.3)
    assert len(said) == 1
    assert said[0].startswith("a dock goal: still deciding after 0.05 s; the threads:\n")
    assert "test_a_decision_still_running_is_reported_once" in said[0]  # this thread's stack, where it waits


def test_callbacks_waiting_for_a_thread_are_reported_once_per_stall() -> None:
    pool = ThreadPoolExecutor(1)
    said: list[str] = []
    watch = ExecutorQueueWatch(SimpleNamespace(_executor=pool), said.append, after=3.0)

    def stall(count: int) -> threading.Event:
        release = threading.Event()
        pool.submit(release.wait, 10.0)  # the only thread, busy
        for _ in range(count):
            pool.submit(lambda: None)
        return release

    def drained() -> None:
        deadline = time.monotonic() + 10.0
        while pool._work_queue.qsize() and time.monotonic() < deadline:
            time.sleep(0.01)

    try:
        watch.look(now=100.0)  # nothing queued
        release = stall(2)
        time.sleep(0.1)
        watch.look(now=101.0)
        watch.look(now=103.5)
        assert said == []  # 2.5 s: not yet
        watch.look(now=104.0)
        watch.look(now=110.0)
        assert len(said) == 1  # once per stall
        assert said[0].startswith("2 callback(s) have waited 3.0 s for a free executor thread; the threads:\n")
        release.set()
        drained()
        watch.look(now=111.0)  # drained: the next stall is news again
        release = stall(1)
        time.sleep(0.1)
        watch.look(now=120.0)
        watch.look(now=123.0)
        assert len(said) == 2 and said[1].startswith("1 callback(s) have waited 3.0 s")
    finally:
        release.set()
        pool.shutdown(wait=True)


def test_an_executor_without_a_thread_pool_is_left_alone() -> None:
    said: list[str] = []
    watch = ExecutorQueueWatch(object(), said.append, after=0.0)
    watch.look(now=1.0)
    watch.look(now=5.0)
    assert said == []
