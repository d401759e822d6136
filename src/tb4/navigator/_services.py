"""Service calls with a bounded wait for the server and for the answer; a second request only where it is safe.

A server can see a request before its reply writer has matched our reader (a known DDS discovery race), and the
reply is then lost, until the server has matched our reader, which on a loaded machine can take more than a
second. For idempotent services (GetState, GetCostmap, IsPathValid, ...) a duplicate request goes out every
`IDEMPOTENT_REASK` seconds without an answer while the earlier ones stay pending: whichever answers first wins.
Every other service (ManageLifecycleNodes, LoadMap, clearing) is asked exactly once. Either way the first request
gets the whole time limit.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

from tb4.core.waits import POLL_BACKSTOP
from tb4.navigator._clients import ClientOwner, ClientSetup
from tb4.navigator.timeouts import NavigatorTimeout
from tb4.ros.qos import REQUESTS
from tb4.ros.replies import service_graph_report

__all__ = ["ServiceCaller", "IDEMPOTENT_REASK"]

IDEMPOTENT_REASK = 1.0  # seconds without an answer before an idempotent request is asked once more


class ServiceCaller(ClientOwner[Any]):
    """Creates clients on first use (or up front with `add`) and calls them with the navigator's limits."""

    def __init__(self, setup: ClientSetup) -> None:
        super().__init__(setup)
        self.requests_sent = 0  # how many requests went out (a test can tell a re-ask from a single call)

    def add(self, srv_type: Any, name: str) -> Any:
        return self._client(name, lambda: self._node.create_client(srv_type, name, qos_profile=REQUESTS))

    def call(
        self,
        srv_type: Any,
        name: str,
        request: Any,
        response_timeout: float | None = None,
        server_timeout: float | None = None,
        *,
        idempotent: bool = False,
    ) -> Any:
        """The response; NavigatorTimeout if the server is missing or does not answer within the limit."""
        client = self.add(srv_type, name)
        limits = self._timeouts()
        discovery = limits.server if server_timeout is None else server_timeout
        self._wait_for_server(client.service_is_ready, "service", name, discovery, lambda: self._graph_report(name))
        limit = limits.response if response_timeout is None else response_timeout
        deadline = time.monotonic() + limit
        reask_at = time.monotonic() + IDEMPOTENT_REASK if idempotent and limit > IDEMPOTENT_REASK else None
        answered = threading.Event()
        pending = [self._send(client, request, answered)]
        try:
            while True:
                for future in pending:
                    if future.done():
                        exc = future.exception()
                        if exc is not None:
                            raise exc
                        return future.result()
                self._check_context(f"a response from service '{name}'")
                now = time.monotonic()
                if now >= deadline:
                    raise NavigatorTimeout(
                        f"timed out after {limit:g} s waiting for a response from service '{name}' "
                        f"({self._server_state(client, name, len(pending))})"
                    )
                if reask_at is not None and now >= reask_at:
                    reask_at = now + IDEMPOTENT_REASK
                    pending.append(self._send(client, request, answered))
                    continue
                until = deadline if reask_at is None else min(deadline, reask_at)
                answered.wait(min(POLL_BACKSTOP, until - now))
        finally:
            for future in pending:
                if not future.done():
                    with contextlib.suppress(Exception):
                        client.remove_pending_request(future)

    def _graph_report(self, name: str) -> str:
        return service_graph_report(self._node, self._node.resolve_service_name(name))

    def _server_state(self, client: Any, name: str, sent: int) -> str:
        """How many requests went unanswered, whether rmw calls the server ready, and what the graph shows of it:
        unanswered requests to a ready server were lost on the way or left untaken, those to a server gone from the
        graph were never answered."""
        asked = f"{sent} request{'s' if sent != 1 else ''} unanswered"
        try:
            ready = "yes" if client.service_is_ready() else "no"
            return f"{asked}; the server is ready: {ready}; the graph shows {self._graph_report(name)}"
        except Exception as exc:  # noqa: BLE001 - a node being destroyed: the timeout is raised all the same
            return f"{asked}; the server's state unknown ({type(exc).__name__}: {exc})"

    def _send(self, client: Any, request: Any, answered: threading.Event) -> Any:
        self._before_send()
        future = client.call_async(request)
        self.requests_sent += 1
        future.add_done_callback(lambda _f: answered.set())
        return future

    def destroy(self) -> None:
        for client in self._clients.values():
            self._node.destroy_client(client)
        self._clients.clear()
