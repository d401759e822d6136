"""SimNode: the node class of every node the simulator serves.

Its publishers and subscriptions come without rclpy's default QoS event handlers. Each handler is a waitable that
the simulator's executor adds to its wait set, in Python, at every wake-up: they were most of the simulator's
waitables, and more than doubled what a wake-up cost in a fleet. All they did was log an incompatible-QoS or
incompatible-type warning, which the process on the other side of the topic logs as well. A caller that wants event
callbacks passes its own.
"""

from __future__ import annotations

from typing import Any

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node

__all__ = ["SimNode"]


class SimNode(Node):
    """rclpy's Node whose publishers and subscriptions have no default QoS event handlers (see the module)."""

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("event_callbacks", PublisherEventCallbacks(use_default_callbacks=False))
        return super().create_publisher(*args, **kwargs)

    def create_subscription(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("event_callbacks", SubscriptionEventCallbacks(use_default_callbacks=False))
        return super().create_subscription(*args, **kwargs)
