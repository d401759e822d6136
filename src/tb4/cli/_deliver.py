"""Deliver one message to every subscriber of a topic from a short-lived CLI process (tb4 pose, press, kidnap).

A fresh writer is matched by readers one by one, and a reader that has not discovered it yet drops the sample:
wait until a subscriber exists and the matched count has been steady for a moment, then publish reliably and
keep the writer alive until every matched subscriber acknowledged it. Every wait is bounded.
"""

from __future__ import annotations

import contextlib
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

from tb4.processes import abandoned_ports_watched
from tb4.rosenv import require_ros

__all__ = ["cli_node", "wait_for_readers", "deliver_once", "ACK_TIMEOUT", "SETTLE"]

ACK_TIMEOUT = 3.0  # s to wait at least for reliable delivery to every matched subscriber
SETTLE = 2.5  # s the matched subscriber count must stay unchanged (and complete) before we publish


@contextlib.contextmanager
def cli_node(name: str, namespace: str) -> Iterator[Any]:
    """A node for one command in its own rclpy session, destroyed (and rclpy shut down) on the way out."""
    require_ros()
    import rclpy

    rclpy.init()
    with abandoned_ports_watched():
        node = rclpy.create_node(name, namespace=namespace or "/")
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def wait_for_readers(
    node: Any,
    publisher: Any,
    topic: str,
    deadline: float,
    settle: float,
    pause: Callable[[float], None] = time.sleep,
    ready: Callable[[int], bool] = lambda matched: matched > 0,
) -> bool:
    """Wait until `ready(matched)` holds and no reader has turned up for `settle` s; False if never ready by
    `deadline` (time.monotonic()). Ready at the deadline but not yet settled counts as ready: someone listens.
    `pause(seconds)` passes the time between looks (a sleep, or spinning the node when it has subscriptions)."""
    steady_since, seen = time.monotonic(), -1
    while True:
        matched = publisher.get_subscription_count()
        known = len(node.get_subscriptions_info_by_topic(topic))
        if matched != seen or matched < known:
            steady_since, seen = time.monotonic(), matched
        is_ready = ready(matched)
        if is_ready and time.monotonic() - steady_since >= settle:
            return True
        if time.monotonic() > deadline:
            return is_ready
        pause(0.05)


def deliver_once(
    node: Any, publisher: Any, topic: str, msg: Any, timeout: float, who: str, hint: str, settle: float = SETTLE
) -> bool:
    """Publish `msg` once on `publisher` (topic name `topic`); False (with a message on stderr) if nobody listens."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + timeout
    if not wait_for_readers(node, publisher, topic, deadline, settle):
        print(f"{who}: nobody subscribes to '{topic}' after {timeout:g} s ({hint})", file=sys.stderr)
        return False
    if hasattr(msg, "header") and not msg.header.stamp.sec:
        msg.header.stamp = node.get_clock().now().to_msg()
    publisher.publish(msg)
    # Our writer may have matched a reader that has not yet matched it back (discovery runs both ways, and on a
    # loaded machine takes seconds): that reader takes the sample only once it has, from a writer still alive.
    # So the writer lives until every reader acknowledged, for what is left of the timeout (ACK_TIMEOUT at least).
    ack_limit = max(ACK_TIMEOUT, deadline - time.monotonic())
    if not publisher.wait_for_all_acked(Duration(seconds=ack_limit)):
        # A subscriber in a killed process stays matched until its DDS lease runs out (about 20 s) and never
        # answers: the live ones have the message by now, so this is a warning, not a failure.
        print(
            f"{who}: not every subscriber acknowledged within {ack_limit:.0f} s (one may have gone away)",
            file=sys.stderr,
        )
    return True
