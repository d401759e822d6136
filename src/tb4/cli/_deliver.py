"""Deliver one message to every subscriber of a topic from a short-lived CLI process (tb4 press, tb4 kidnap).

A fresh writer is matched by readers one by one, and a reader that has not discovered it yet drops the sample:
wait until a subscriber exists, until the matched count has been steady for a moment, then publish reliably and
keep the writer alive until every matched subscriber acknowledged it. Every wait is bounded.
"""

from __future__ import annotations

import sys
import time
from typing import Any

__all__ = ["deliver_once", "ACK_TIMEOUT", "SETTLE"]

ACK_TIMEOUT = 3.0  # s to wait for reliable delivery to every matched subscriber
SETTLE = 2.5  # s the matched subscriber count must stay unchanged (and complete) before we publish


def deliver_once(
    node: Any, publisher: Any, topic: str, msg: Any, timeout: float, who: str, hint: str, settle: float = SETTLE
) -> bool:
    """Publish `msg` once on `publisher` (topic name `topic`); False (with a message on stderr) if nobody listens."""
    from rclpy.duration import Duration

    deadline = time.monotonic() + timeout
    while publisher.get_subscription_count() == 0:
        if time.monotonic() > deadline:
            print(f"{who}: nobody subscribes to '{topic}' after {timeout:g} s ({hint})", file=sys.stderr)
            return False
        time.sleep(0.05)
    count, steady_since = publisher.get_subscription_count(), time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.05)
        matched, known = publisher.get_subscription_count(), len(node.get_subscriptions_info_by_topic(topic))
        if matched != count or matched < known:
            count, steady_since = matched, time.monotonic()
        elif time.monotonic() - steady_since >= settle:
            break
    if hasattr(msg, "header") and not msg.header.stamp.sec:
        msg.header.stamp = node.get_clock().now().to_msg()
    publisher.publish(msg)
    if not publisher.wait_for_all_acked(Duration(seconds=ACK_TIMEOUT)):
        # A subscriber in a killed process stays matched until its DDS lease runs out (about 20 s) and never
        # answers: the live ones have the message by now, so this is a warning, not a failure.
        print(
            f"{who}: not every subscriber acknowledged within {ACK_TIMEOUT:g} s (one may have gone away)",
            file=sys.stderr,
        )
    return True
