"""A node in a context of its own, spun by a background thread: for watchers that live beside other ROS code in
the same process (the run monitor, the MCAP recorder) without sharing its executor."""

from __future__ import annotations

import threading

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

__all__ = ["BackgroundNode"]


class BackgroundNode:
    """Create with a name; add subscriptions to `.node`, then call `start()`; `close()` ends it all."""

    def __init__(self, name: str, namespace: str = "") -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node: Node = rclpy.create_node(name, namespace=namespace or "/", context=self.context)
        self._executor = SingleThreadedExecutor(context=self.context)
        self._executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)

    def start(self) -> None:
        self._thread.start()

    def _spin(self) -> None:
        while self.context.ok():
            try:
                self._executor.spin_once(timeout_sec=0.1)
            except Exception:  # shutdown races end the loop; anything else is retried on the next turn
                if not self.context.ok():
                    return

    def close(self) -> None:
        rclpy.try_shutdown(context=self.context)  # ends the spin loop first
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self._executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
