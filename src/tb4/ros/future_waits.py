"""Waiting on a ROS future by spinning a node ourselves (for callers without an executor thread).

The one timeout type and the non-spinning waits live in tb4.core.waits; this adds only what needs rclpy.
"""

from __future__ import annotations

from typing import Any

from tb4.core.waits import Deadline

__all__ = ["spin_until_future"]


def spin_until_future(node: Any, future: Any, timeout: float, what: str) -> Any:
    """Spin `node` until `future` completes; raise WaitTimeout naming `what` after `timeout` seconds (wall)."""
    from rclpy.executors import SingleThreadedExecutor

    deadline = Deadline(timeout)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        while not future.done():
            remaining = deadline.remaining()
            if remaining <= 0:
                raise deadline.timeout_error(what)
            executor.spin_until_future_complete(future, timeout_sec=min(remaining, 0.5))
    finally:
        executor.remove_node(node)
        executor.shutdown(timeout_sec=0)
    return future.result()
