"""A Foxglove WebSocket client for the tests, speaking the protocol as the Foxglove app does: the `foxglove.sdk.v1`
subprotocol, the server's JSON `serverInfo` and `advertise`, a JSON `subscribe`, and binary message-data frames
(opcode 1, subscription id, log time, then the message bytes, here CDR) decoded with rclpy. Every wait is bounded."""

from __future__ import annotations

import importlib
import json
import struct
import time
from collections import deque
from collections.abc import Callable, Iterable
from typing import Any

from rclpy.serialization import deserialize_message
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

SUBPROTOCOL = "foxglove.sdk.v1"
MESSAGE_DATA = 1  # the server's binary opcode for a message
HEADER = struct.Struct("<BIQ")  # opcode, subscription id, log time (ns)
UNREAD_KEPT = 500  # messages kept per topic for a later next_message (the newest)


def message_class(schema_name: str) -> Any:
    """`nav_msgs/msg/Odometry` -> the rclpy message class."""
    package, _, name = schema_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


class FoxgloveClient:
    """One connection. `channels` maps topic -> the advertised channel (id, encoding, schemaName, schema...)."""

    def __init__(self, url: str, *, timeout: float = 10.0, **connect_kwargs: Any) -> None:
        self._connection = connect(
            url, subprotocols=[SUBPROTOCOL], open_timeout=timeout, max_size=None, **connect_kwargs
        )
        self.ws: ClientConnection = self._connection.__enter__()
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}
        self.statuses: list[dict[str, Any]] = []
        self._subscriptions: dict[int, dict[str, Any]] = {}
        self._next_id = 1
        self._unread: dict[str, deque[tuple[int, bytes]]] = {}  # messages read while waiting for another topic

    def close(self) -> None:
        self._connection.__exit__(None, None, None)

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- control messages -------------------------------------------------------------------------------------
    def _handle_text(self, text: str) -> None:
        message = json.loads(text)
        op = message.get("op")
        if op == "serverInfo":
            self.server_info = message
        elif op == "advertise":
            for channel in message["channels"]:
                self.channels[channel["topic"]] = channel
        elif op == "status":
            self.statuses.append(message)

    def wait_for_channels(self, topics: Iterable[str], timeout: float = 20.0) -> dict[str, dict[str, Any]]:
        """Read until every topic is advertised; the channels by topic."""
        wanted = set(topics)
        deadline = time.monotonic() + timeout
        while not wanted <= set(self.channels):
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"not advertised within {timeout} s: {sorted(wanted - set(self.channels))}")
            self._receive(remaining)
        return {topic: self.channels[topic] for topic in wanted}

    def wait_for_status(self, predicate: Callable[[dict[str, Any]], bool], timeout: float = 10.0) -> dict[str, Any]:
        deadline = time.monotonic() + timeout
        while True:
            for status in self.statuses:
                if predicate(status):
                    return status
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no such status within {timeout} s: {self.statuses}")
            self._receive(remaining)

    def subscribe(self, topics: Iterable[str]) -> None:
        subscriptions = []
        for topic in topics:
            channel = self.channels[topic]
            self._subscriptions[self._next_id] = channel
            subscriptions.append({"id": self._next_id, "channelId": channel["id"]})
            self._next_id += 1
        self.send({"op": "subscribe", "subscriptions": subscriptions})

    def send(self, message: dict[str, Any] | str | bytes) -> None:
        self.ws.send(json.dumps(message) if isinstance(message, dict) else message)

    # --- data -------------------------------------------------------------------------------------------------
    def _receive(self, timeout: float) -> tuple[str, int, bytes] | None:
        """One frame: a message's (topic, log time, CDR bytes), or None for a control message."""
        try:
            frame = self.ws.recv(timeout=max(timeout, 0.001))
        except TimeoutError:
            return None
        if isinstance(frame, str):
            self._handle_text(frame)
            return None
        if frame[0] != MESSAGE_DATA:
            return None
        _, subscription, log_time = HEADER.unpack_from(frame)
        channel = self._subscriptions.get(subscription)
        if channel is None:
            raise AssertionError(f"data for subscription {subscription}, which this client never made")
        return channel["topic"], log_time, frame[HEADER.size :]

    def next_message(
        self, topics: Iterable[str], timeout: float = 20.0, predicate: Callable[[Any], bool] = lambda m: True
    ) -> tuple[str, int, Any]:
        """The next message on one of `topics` that satisfies `predicate`: (topic, log time, decoded message)."""
        wanted = set(topics)
        deadline = time.monotonic() + timeout
        while True:
            for topic in wanted:
                unread = self._unread.get(topic)
                while unread:
                    log_time, data = unread.popleft()
                    message = deserialize_message(data, message_class(self.channels[topic]["schemaName"]))
                    if predicate(message):
                        return topic, log_time, message
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no message on {sorted(wanted)} within {timeout} s")
            got = self._receive(remaining)
            if got is not None:
                self._unread.setdefault(got[0], deque(maxlen=UNREAD_KEPT)).append(got[1:])

    def count(self, seconds: float) -> dict[str, int]:
        """Messages per topic received during `seconds` (wall)."""
        counts: dict[str, int] = {}
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                got = self._receive(remaining)
            except ConnectionClosed:
                break
            if got is not None:
                counts[got[0]] = counts.get(got[0], 0) + 1
        return counts
