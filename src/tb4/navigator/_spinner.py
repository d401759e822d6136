"""Waiting on futures through events instead of spinning.

Upstream calls rclpy.spin_until_future_complete on the navigator node, which breaks when the node also belongs to
the user's executor. Here a background thread spins the node (tb4.ros.background.BackgroundSpinner with `adopt`:
if the user adds the node to their own executor, rclpy moves it there, and the thread takes it back when the user
lets go), so futures complete in the background and every wait is a threading.Event with a deadline.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from tb4.navigator.timeouts import NavigatorTimeout

__all__ = ["wait_for_future", "wait_until"]

_BACKSTOP = 0.05  # seconds between done() checks behind an event that normally fires first


def wait_for_future(future: Any, timeout: float, what: str) -> Any:
    """The future's result, waiting at most `timeout` wall seconds; NavigatorTimeout names `what` otherwise.

    rclpy runs a future's done-callbacks through the executor that last executed its client, which may be one the
    user has stopped since (rclpy.spin_once, their own executor); so the event is backed by a cheap done() check.
    """
    if not future.done():
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        deadline = time.monotonic() + timeout
        while not future.done():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise NavigatorTimeout(f"timed out after {timeout:g} s waiting for {what}")
            done.wait(min(_BACKSTOP, remaining))
    exc = future.exception()
    if exc is not None:
        raise exc
    return future.result()


def wait_until(predicate: Callable[[], bool], timeout: float, period: float = 0.02) -> bool:
    """Poll a cheap graph query (no event exists for discovery) until true or `timeout` wall seconds pass."""
    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return False
        time.sleep(min(period, remaining))
