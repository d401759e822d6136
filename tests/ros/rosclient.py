"""A raw-rclpy test client: its own context and a spinning executor thread, every wait bounded."""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

import rclpy
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile

from tb4.core.waits import WaitTimeout, wait_for_future


class RosClient:
    def __init__(self, name: str = "test_client", namespace: str = "") -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, namespace=namespace or "/", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()
        self._clients: dict[tuple[Any, str], Any] = {}

    def _spin(self) -> None:
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:
                if not self.context.ok():
                    return
                raise

    def close(self) -> None:
        rclpy.try_shutdown(context=self.context)  # ends the spin thread first, then tear down
        self._thread.join(timeout=2.0)
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()

    # --- topics ------------------------------------------------------------------------------------------------
    def latest(self, msg_type: Any, topic: str, qos: QoSProfile | int = 10) -> Callable[[], Any]:
        """Subscribe and return a getter for the newest message (None until one arrives)."""
        box: dict[str, Any] = {"msg": None}
        self.node.create_subscription(msg_type, topic, lambda m: box.__setitem__("msg", m), qos)
        return lambda: box["msg"]

    def wait_for(
        self,
        getter: Callable[[], Any],
        predicate: Callable[[Any], bool] = lambda m: m is not None,
        timeout: float = 20.0,
        what: str = "a message",
    ) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = getter()
            if value is not None and predicate(value):
                return value
            time.sleep(0.01)
        raise WaitTimeout(f"timed out after {timeout} s waiting for {what} (last: {getter()!r:.300})")

    # --- actions and services ----------------------------------------------------------------------------------
    def action(
        self, action_type: Any, name: str, goal: Any, timeout: float = 60.0, feedback: list | None = None
    ) -> tuple[int, Any]:
        """Send a goal; returns (status, result). status is GoalStatus (4 succeeded, 5 canceled, 6 aborted),
        or -1 when the goal was rejected."""
        handle = self.send_goal(action_type, name, goal, feedback)
        if not handle.accepted:
            return -1, None
        response = wait_for_future(handle.get_result_async(), timeout, f"result of {name}")
        return response.status, response.result

    def send_goal(self, action_type: Any, name: str, goal: Any, feedback: list | None = None) -> Any:
        key = (action_type, name)
        if key not in self._clients:
            self._clients[key] = ActionClient(self.node, action_type, name)
        client = self._clients[key]
        if not client.wait_for_server(timeout_sec=20.0):
            raise WaitTimeout(f"no action server '{name}' after 20 s")
        callback = (lambda m: feedback.append(m.feedback)) if feedback is not None else None
        return wait_for_future(client.send_goal_async(goal, feedback_callback=callback), 10.0, f"{name} acceptance")

    def service(self, srv_type: Any, name: str, request: Any, timeout: float = 10.0) -> Any:
        client = self.node.create_client(srv_type, name)
        if not client.wait_for_service(timeout_sec=20.0):
            raise WaitTimeout(f"no service '{name}' after 20 s")
        return wait_for_future(client.call_async(request), timeout, f"response of {name}")
