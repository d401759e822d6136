"""What the navigator's action clients (_task_client.TaskClient) and service clients (_services.ServiceCaller)
share: the node, the navigator's wait limits, the hooks around creating a client and sending a request, the clients
by name, and the bounded wait for a server that ends in a NavigatorTimeout naming it."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from rclpy.node import Node

from tb4.core.waits import wait_until
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts, missing_server

__all__ = ["ClientSetup", "ClientOwner"]

_C = TypeVar("_C")


def _nothing() -> None:
    pass


def _any_context(_what: str) -> None:
    pass


@dataclass(frozen=True)
class ClientSetup:
    """How the navigator's clients reach its node: `timeouts` gives the current limits (the user may change them
    between calls); `before_send` runs before each request goes out; `creating` is held while a client is built
    (rclpy registers a client with its node before the client is complete, so the navigator keeps its executor
    thread out of the node meanwhile); `check_context(what)` runs on each turn of a wait and raises if nothing can
    arrive any more (the ROS context was shut down)."""

    node: Node
    timeouts: Callable[[], NavigatorTimeouts]
    before_send: Callable[[], None] = _nothing
    creating: Callable[[], contextlib.AbstractContextManager[Any]] = contextlib.nullcontext
    check_context: Callable[[str], None] = _any_context


class ClientOwner(Generic[_C]):
    """Clients of one kind on the navigator's node, created once each by name (see ClientSetup)."""

    def __init__(self, setup: ClientSetup) -> None:
        self._node = setup.node
        self._timeouts = setup.timeouts
        self._before_send = setup.before_send
        self._creating = setup.creating
        self._check_context = setup.check_context
        self._clients: dict[str, _C] = {}

    def _client(self, name: str, create: Callable[[], _C]) -> _C:
        """The client called `name`, created now (under `creating`) if it is the first use."""
        if name not in self._clients:
            with self._creating():
                self._clients[name] = create()
        return self._clients[name]

    def _wait_for_server(
        self,
        is_ready: Callable[[], bool],
        kind: str,
        name: str,
        limit: float,
        graph_report: Callable[[], str] | None = None,
    ) -> None:
        """Return once `is_ready()`; after `limit` s without, log and raise a NavigatorTimeout naming the server
        (and what `graph_report` says the graph shows of it: a server in the graph but not ready is another fault
        than none at all)."""
        if not wait_until(is_ready, limit):
            message = missing_server(kind, name, self._node.get_namespace(), limit)
            if graph_report is not None:
                message += f" (the graph shows {graph_report()})"
            self._node.get_logger().error(message)
            raise NavigatorTimeout(message)
