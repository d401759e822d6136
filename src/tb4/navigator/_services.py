"""Service calls with a bounded wait for the server and for the answer."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.node import Node

from tb4.navigator._spinner import wait_for_future, wait_until
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts, missing_server

__all__ = ["ServiceCaller"]


class ServiceCaller:
    """Creates clients on first use (or up front with `add`) and calls them with the navigator's limits."""

    def __init__(
        self, node: Node, timeouts: Callable[[], NavigatorTimeouts], before_send: Callable[[], None] | None = None
    ) -> None:
        self._node = node
        self._before_send = before_send or (lambda: None)
        self._timeouts = timeouts
        self._clients: dict[str, Any] = {}

    def add(self, srv_type: Any, name: str) -> Any:
        if name not in self._clients:
            self._clients[name] = self._node.create_client(srv_type, name)
        return self._clients[name]

    def call(
        self,
        srv_type: Any,
        name: str,
        request: Any,
        response_timeout: float | None = None,
        server_timeout: float | None = None,
    ) -> Any:
        client = self.add(srv_type, name)
        limits = self._timeouts()
        discovery = limits.server if server_timeout is None else server_timeout
        if not wait_until(client.service_is_ready, discovery):
            message = missing_server("service", name, self._node.get_namespace(), discovery)
            self._node.get_logger().error(message)
            raise NavigatorTimeout(message)
        limit = limits.response if response_timeout is None else response_timeout
        # A server can see the request before its reply writer has matched our reader (a known DDS discovery
        # race); the reply is then lost. Ask once more after half the limit: the services we call are idempotent.
        self._before_send()
        first = client.call_async(request)
        try:
            return wait_for_future(first, limit / 2.0, f"a response from service '{name}'")
        except NavigatorTimeout:
            client.remove_pending_request(first)
        self._before_send()
        return wait_for_future(client.call_async(request), limit / 2.0, f"a response from service '{name}'")

    def destroy(self) -> None:
        for client in self._clients.values():
            self._node.destroy_client(client)
        self._clients.clear()
