"""Waiting on ROS futures with a deadline and a message that says what did not arrive."""

from __future__ import annotations

import time
from typing import Any

__all__ = ["WaitTimeout", "spin_until_future", "wait_future"]


class WaitTimeout(TimeoutError):
    """Something we waited for did not happen in time; the message names it."""


def spin_until_future(node: Any, future: Any, timeout: float, what: str) -> Any:
    """Spin `node` until `future` completes; raise WaitTimeout naming `what` after `timeout` seconds (wall)."""
    from rclpy.executors import SingleThreadedExecutor

    deadline = time.monotonic() + timeout
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while not future.done():
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise WaitTimeout(f"timed out after {timeout:g} s waiting for {what}")
            executor.spin_until_future_complete(future, timeout_sec=min(remaining, 0.5))
    finally:
        executor.remove_node(node)
        executor.shutdown(timeout_sec=0)
    return future.result()


def wait_future(future: Any, timeout: float, what: str) -> Any:
    """Wait (without spinning) for a future that another executor completes."""
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() >= deadline:
            raise WaitTimeout(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.002)
    return future.result()
