"""Fixtures for end-to-end tests: a real `tb4 sim` process and a small raw-rclpy client with bounded waits.

(tests/conftest.py starts the simulator, `start_simulator`, for these and the DDS tests.)
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest


class E2ERos:
    """Raw rclpy in its own context, spun by a thread: subscribe to the newest message, publish, send goals."""

    def __init__(self, name: str = "e2e_client") -> None:
        from tb4.ros.background import BackgroundNode

        # tb4's one background spinner: a SingleThreadedExecutor (rclpy's MultiThreadedExecutor falls behind a
        # fast simulator), paused while an action client is built (rclpy registers it before it is complete, and
        # a spin turn in between killed the spin thread: "'ActionClient' object has no attribute '_lock'")
        self._background = BackgroundNode(name, signal_handlers=False)
        self.context = self._background.context
        self.node = self._background.node
        self._background.start()

    def close(self) -> None:
        self._background.close()

    def latest(self, msg_type: Any, topic: str, qos: Any = 10) -> Callable[[], Any]:
        box: dict[str, Any] = {"msg": None}
        self.node.create_subscription(msg_type, topic, lambda m: box.__setitem__("msg", m), qos)
        return lambda: box["msg"]

    def collect(self, msg_type: Any, topic: str, qos: Any = 10) -> list[Any]:
        """Every message on `topic` from now on (for topics that carry few)."""
        received: list[Any] = []
        self.node.create_subscription(msg_type, topic, received.append, qos)
        return received

    @staticmethod
    def wait_for(
        getter: Callable[[], Any],
        predicate: Callable[[Any], bool] = lambda v: v is not None,
        timeout: float = 30.0,
        what: str = "a message",
    ) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = getter()
            if value is not None and predicate(value):
                return value
            time.sleep(0.02)
        raise AssertionError(f"timed out after {timeout} s waiting for {what} (last: {getter()!r:.300})")

    def send_goal(self, action_type: Any, name: str, goal: Any, timeout: float = 20.0) -> Any:
        """Send a goal and wait for acceptance; returns the goal handle."""
        from tb4.ros.action_client import ActionClient

        with self._background.paused():
            client = ActionClient(self.node, action_type, name)
        if not client.wait_for_server(timeout_sec=timeout):
            raise AssertionError(f"no action server '{name}' after {timeout} s")
        future = client.send_goal_async(goal)
        handle = self.wait_for(
            lambda: future.result() if future.done() else None, timeout=timeout, what=f"{name} acceptance"
        )
        assert handle.accepted, f"{name} goal rejected"
        return handle

    def result(self, handle: Any, timeout: float = 60.0) -> Any:
        future = handle.get_result_async()
        return self.wait_for(lambda: future.result() if future.done() else None, timeout=timeout, what="a result")


@pytest.fixture(scope="session")
def e2e_ros_class() -> type[E2ERos]:
    """The client class, for module-scoped fixtures (test modules cannot import a conftest portably)."""
    pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
    return E2ERos


@pytest.fixture
def ros() -> Iterator[E2ERos]:
    pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
    client = E2ERos()
    yield client
    client.close()


@pytest.fixture
def busy_port() -> Iterator[int]:
    """A loopback port something else already listens on."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        yield int(taken.getsockname()[1])
