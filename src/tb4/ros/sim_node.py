"""SimNode: the node class of every node the simulator serves.

Its publishers and subscriptions come without rclpy's default QoS event handlers. Each handler is a waitable that
the simulator's executor adds to its wait set, in Python, at every wake-up: they were most of the simulator's
waitables, and more than doubled what a wake-up cost in a fleet. All they did was log an incompatible-QoS or
incompatible-type warning, which the process on the other side of the topic logs as well. A caller that wants event
callbacks passes its own.

Each subscription takes its messages one at a time, in the order they came, as an rclcpp node's does: it has a
mutually exclusive callback group of its own. The simulator's executor has many threads, and in a reentrant group
rclpy takes a subscription's next message as soon as the last one is taken, so two messages of one topic ran side by
side and could land in the world in either order: of two initial poses sent back to back, amcl kept the first, and a
stop on cmd_vel could be overtaken by the drive command before it.
"""

from __future__ import annotations

from typing import Any

from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node

__all__ = ["SimNode"]


class SimNode(Node):
    """rclpy's Node whose publishers and subscriptions have no default QoS event handlers, and whose subscriptions
    each take their messages in order (see the module)."""

    def create_publisher(self, *args: Any, **kwargs: Any) -> Any:
        kwargs.setdefault("event_callbacks", PublisherEventCallbacks(use_default_callbacks=False))
        return super().create_publisher(*args, **kwargs)

    def create_subscription(self, *args: Any, **kwargs: Any) -> Any:
        """Node.create_subscription, in a mutually exclusive callback group of the subscription's own.

        Raises:
            ValueError: a `callback_group` was given: a shared group would let messages overtake each other again
                (reentrant) or hold one topic's messages behind another's callbacks (mutually exclusive).
        """
        if kwargs.get("callback_group") is not None:
            raise ValueError("a simulator subscription has a callback group of its own: pass none")
        kwargs["callback_group"] = MutuallyExclusiveCallbackGroup()
        kwargs.setdefault("event_callbacks", SubscriptionEventCallbacks(use_default_callbacks=False))
        return super().create_subscription(*args, **kwargs)
