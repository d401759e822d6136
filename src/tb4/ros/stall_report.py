"""Saying where the simulator's threads are when a request waits too long.

A client's goal or service call that gets no answer is reported by the client ("timed out waiting for undock
acceptance"); the simulator's side then said nothing, so a stall could not be told from a lost message. Two looks
say it in the simulator's log, with every thread's stack: a goal decision still running after STALL_REPORT_AFTER
seconds (`SlowDecisionReport`), and callbacks queued for the executor's threads that long (`ExecutorQueueWatch`:
every thread busy). Neither changes what the simulator does.
"""

from __future__ import annotations

import sys
import threading
import time
import traceback
from collections.abc import Callable
from typing import Any

__all__ = ["STALL_REPORT_AFTER", "thread_stacks", "SlowDecisionReport", "ExecutorQueueWatch"]

STALL_REPORT_AFTER = 3.0  # wall s a decision may take, or callbacks may wait for a thread, before it is reported
_FRAMES_PER_THREAD = 6  # innermost frames shown per thread


def thread_stacks() -> str:
    """Every thread of this process with its innermost frames, one block per thread."""
    names = {thread.ident: thread.name for thread in threading.enumerate()}
    blocks = []
    for ident, frame in sys._current_frames().items():
        frames = traceback.extract_stack(frame)[-_FRAMES_PER_THREAD:]
        lines = [f"  {f.filename}:{f.lineno} {f.name}: {(f.line or '').strip()}" for f in frames]
        blocks.append("\n".join([f"thread {names.get(ident, ident)}:", *lines]))
    return "\n".join(blocks)


class SlowDecisionReport:
    """A context manager around one decision (a goal callback): if it is still running after `after` seconds,
    `report(text)` gets what it is and every thread's stack, once."""

    def __init__(self, what: str, report: Callable[[str], object], after: float | None = None) -> None:
        self._what = what
        self._report = report
        after = STALL_REPORT_AFTER if after is None else after
        self._timer = threading.Timer(after, self._fire, args=(after,))
        self._timer.daemon = True

    def _fire(self, after: float) -> None:
        self._report(f"{self._what}: still deciding after {after:g} s; the threads:\n{thread_stacks()}")

    def __enter__(self) -> SlowDecisionReport:
        self._timer.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._timer.cancel()


class ExecutorQueueWatch:
    """Looks, when called, at how many callbacks wait for a thread of a rclpy MultiThreadedExecutor; when some have
    waited (the queue never empty) for `after` seconds, `report(text)` gets the count and every thread's stack, once
    per such stall."""

    def __init__(self, executor: Any, report: Callable[[str], object], after: float | None = None) -> None:
        pool = getattr(executor, "_executor", None)  # rclpy's ThreadPoolExecutor (rclpy 7 and 9)
        self._queue = getattr(pool, "_work_queue", None)
        self._report = report
        self._after = STALL_REPORT_AFTER if after is None else after
        self._since: float | None = None  # monotonic time the queue was first seen non-empty in this stall
        self._reported = False

    def look(self, now: float | None = None) -> None:
        """One look (the simulator's serving thread calls it twice a second); `now`: monotonic seconds."""
        if self._queue is None:
            return
        now = time.monotonic() if now is None else now
        waiting = self._queue.qsize()
        if waiting == 0:
            self._since, self._reported = None, False
            return
        if self._since is None:
            self._since = now
        elif not self._reported and now - self._since >= self._after:
            self._reported = True
            self._report(
                f"{waiting} callback(s) have waited {now - self._since:.1f} s for a free executor thread; "
                f"the threads:\n{thread_stacks()}"
            )
