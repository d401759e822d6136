"""Bounded waiting, one home: every wait in tb4 has a limit and ends in WaitTimeout naming what did not happen.

The helpers are duck-typed over what they wait for (a predicate, or anything with done()/add_done_callback()/
result()/exception() such as an rclpy Future), so they carry no ROS import.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

__all__ = ["WaitTimeout", "Deadline", "POLL_BACKSTOP", "wait_until", "wait_for_future"]

#: Seconds between done() checks behind an event that normally fires first (its callback may never run).
POLL_BACKSTOP = 0.05


class WaitTimeout(TimeoutError):
    """Something we waited for did not happen in time; the message names it."""


class Deadline:
    """A wall-clock (monotonic) limit that a loop counts down against."""

    def __init__(self, timeout: float, clock: Callable[[], float] = time.monotonic) -> None:
        if not (timeout >= 0 and not math.isnan(timeout)):
            raise ValueError(f"a timeout must be a non-negative number of seconds, got {timeout!r}")
        self.timeout = float(timeout)
        self._clock = clock
        self.at = clock() + self.timeout

    def remaining(self) -> float:
        """Seconds left, never below zero."""
        return max(0.0, self.at - self._clock())

    @property
    def expired(self) -> bool:
        return self._clock() >= self.at

    def timeout_error(self, what: str, error: type[WaitTimeout] = WaitTimeout) -> WaitTimeout:
        """The exception for a wait on `what` that ran out."""
        return error(f"timed out after {self.timeout:g} s waiting for {what}")


def wait_until(
    predicate: Callable[[], bool],
    timeout: float,
    what: str | None = None,
    period: float = 0.02,
    error: type[WaitTimeout] = WaitTimeout,
) -> bool:
    """Poll a cheap predicate until it is true (True) or `timeout` wall seconds pass: then False, or `error`
    naming `what` if `what` is given."""
    deadline = Deadline(timeout)
    while True:
        if predicate():
            return True
        remaining = deadline.remaining()
        if remaining <= 0:
            if what is not None:
                raise deadline.timeout_error(what, error)
            return False
        time.sleep(min(period, remaining))


def wait_for_future(
    future: Any,
    timeout: float,
    what: str,
    error: type[WaitTimeout] = WaitTimeout,
    check: Callable[[], None] | None = None,
) -> Any:
    """The future's result, waiting (without spinning) at most `timeout` wall seconds; `error` names `what`
    otherwise. The future's own exception is raised as is. `check`, if given, runs at every turn of the wait and
    may raise to end it early (the navigator's context and server-liveness checks).

    rclpy runs a future's done-callbacks through the executor that last executed its client, which may be one the
    user has stopped since (rclpy.spin_once, their own executor); so the event is backed by a cheap done() check.
    """
    if not future.done():
        done = threading.Event()
        future.add_done_callback(lambda _f: done.set())
        deadline = Deadline(timeout)
        while not future.done():
            if check is not None:
                check()
            remaining = deadline.remaining()
            if remaining <= 0:
                raise deadline.timeout_error(what, error)
            done.wait(min(POLL_BACKSTOP, remaining))
    exc = future.exception()
    if exc is not None:
        raise exc
    return future.result()
