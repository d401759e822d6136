"""FoxgloveLive: the Foxglove SDK's WebSocket server, fed the robots' topics as they arrive over DDS.

A node in a context of its own (tb4.ros.background.BackgroundNode, as the MCAP recorder's) subscribes to each topic
as serialized CDR and logs the bytes unchanged on a Foxglove channel whose schema is the topic's full ros2msg
definition (tb4.runner.mcap_record.message_definition), so the app decodes them as it decodes a ROS 2 recording.
The topics are the recorder's (RECORDED_TOPICS) and LIVE_TOPICS; DERIVED_TOPICS adds PoseArray views of the particle
cloud and the goals for the 3D panel (tb4.foxglove.reframe).

A topic is subscribed over DDS only while some Foxglove client subscribes to one of its channels (and LINGER
seconds after), so serving with no client connected costs nothing, and the simulator, which publishes only to
subscribers, does not even produce the messages. Topics the simulator publishes once (map, tf_static, goals, the
global costmap) are kept, and sent again when a client subscribes to a channel already fed: the SDK keeps no
message for a late subscriber, as a transient-local DDS writer does.

Each channel sends at most one message per `period` wall seconds (grids and particle clouds less often than the
rest), the newest winning: at --rate max the simulator publishes far faster than any display draws, and a grid of a
few hundred kilobytes at that pace would fill a client's buffer. A message held back is sent when its period ends,
so the last one always arrives.

Time: with `sim_time`, every message is logged at the latest /clock time and the server announces that time (the
Time capability), as foxglove_bridge does with use_sim_time; the headers' stamps are sim time too. A message that
comes before the first /clock is held (the newest of each topic, a latched topic's kept ones) and sent when that
clock comes: there is no sim time to log it at before, and time zero would put it at the start of the timeline,
minutes or hours before the messages around it. The simulator sends /clock only once it has matched our reader,
which on a loaded machine can come seconds after the other topics' first messages. Without `sim_time` (a real
robot), at the wall time the message arrived.
"""

from __future__ import annotations

import importlib
import importlib.util
import struct
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from tb4.extras import MissingExtraError
from tb4.foxglove import DEFAULT_HOST, DEFAULT_PORT, FoxgloveError
from tb4.foxglove.reframe import CdrError, goals_to_pose_array, particle_cloud_to_pose_array
from tb4.runner.mcap_record import RECORDED_TOPICS, message_definition

__all__ = [
    "DERIVED_TOPICS",
    "FoxgloveError",
    "FoxgloveLive",
    "LIVE_TOPICS",
    "SERVED_TOPICS",
    "require_foxglove",
]

#: What the app draws that a recording does not keep: (topic, type, qos) as in RECORDED_TOPICS.
LIVE_TOPICS: tuple[tuple[str, str, str], ...] = (
    ("global_costmap/costmap", "nav_msgs/msg/OccupancyGrid", "latched"),
    ("local_costmap/costmap", "nav_msgs/msg/OccupancyGrid", "default"),
    ("particle_cloud", "nav2_msgs/msg/ParticleCloud", "default"),
)
SERVED_TOPICS = RECORDED_TOPICS + LIVE_TOPICS
#: topic -> (the derived channel's topic, its type, the function that cuts its bytes from the topic's)
DERIVED_TOPICS: dict[str, tuple[str, str, Callable[[bytes], bytes]]] = {
    "particle_cloud": ("particle_cloud/poses", "geometry_msgs/msg/PoseArray", particle_cloud_to_pose_array),
    "goals": ("goals/poses", "geometry_msgs/msg/PoseArray", goals_to_pose_array),
}
HEAVY_TYPES = {"nav_msgs/msg/OccupancyGrid": 0.2, "nav2_msgs/msg/ParticleCloud": 0.2}  # wall s between two sent
PERIOD = 1.0 / 60.0  # wall s between two messages sent on any other channel
UNTHROTTLED = {"tf_static"}  # several writers' latched messages: the newest must not replace another's
KEEP = {"tf_static": 16}  # latched messages kept per topic (distinct ones): one writer's each; others keep one
LINGER = 2.0  # wall s a DDS subscription outlives its last Foxglove subscriber (a client may flip subscriptions)
RESEND_PERIOD = 0.5  # wall s between two re-sends of one topic's kept messages (a client may flood subscriptions)
TIME_PERIOD = 0.05  # wall s between two announcements of the server's time
BACKLOG = 256  # messages the SDK buffers per client before it drops the oldest (its default: 1024)
IDLE_WAKE = 1.0  # wall s the worker sleeps with nothing to do
CLOCK_WARN = 10.0  # wall s without a first /clock (sim time) before the user is told that messages wait for one


def require_foxglove() -> Any:
    """The Foxglove SDK module, or MissingExtraError naming the pip command.

    Returns:
        The imported `foxglove` module.

    Raises:
        MissingExtraError: the [foxglove] extra (foxglove-sdk) is not installed.
    """
    if importlib.util.find_spec("foxglove") is None:
        raise MissingExtraError(
            "serving Foxglove needs the 'foxglove' extra (foxglove-sdk not installed): "
            "pip install 'turtlebot4-navigator[foxglove]'"
        )
    return importlib.import_module("foxglove")


def _clock_nanoseconds(data: bytes) -> int | None:
    """The time in a serialized rosgraph_msgs/Clock (plain CDR: encapsulation, int32 sec, uint32 nanosec)."""
    if len(data) < 12 or data[0] != 0 or data[1] not in (0, 1):
        return None
    sec, nanosec = struct.unpack_from("<iI" if data[1] == 1 else ">iI", data, 4)
    return max(0, sec * 1_000_000_000 + nanosec)


@dataclass(eq=False)
class _Topic:
    """One DDS topic served: its channels (the topic's own, and a derived one), the subscription while wanted, the
    latched messages kept, and the message held back by the rate limit."""

    name: str  # as the node subscribes it (relative to the node's namespace for one robot)
    full: str  # the channel's topic
    msg_type: Any
    qos: Any
    latched: bool
    keep: int
    period: float
    channels: list[tuple[Any, Callable[[bytes], bytes] | None]] = field(default_factory=list)
    subscription: Any = None
    wanted: int = 0  # Foxglove subscriptions to its channels
    unwanted_since: float = 0.0
    kept: deque[bytes] = field(default_factory=deque)
    next_send: float = 0.0
    held: bytes | None = None
    resend: bool = False
    last_resend: float = -RESEND_PERIOD
    sent: int = 0
    bad: int = 0


class _Listener:
    """The SDK's ServerListener: each (un)subscription, handed on without ever raising into the server."""

    def __init__(self, owner: FoxgloveLive) -> None:
        self._owner = owner

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self._owner._subscribed(int(channel.id), +1)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        self._owner._subscribed(int(channel.id), -1)


class FoxgloveLive:
    """A Foxglove WebSocket server on `host`:`port`, fed the topics of the robots given to serve().

    The server binds at once, so a port in use fails here, before anything else starts; serve() then builds the
    channels and the node. close() ends both.

    Args:
        host: the address to listen on (loopback unless the user asked otherwise: tb4.foxglove.foxglove_options).
        port: the port (0: any free one; `port` then says which).
        sim_time: log messages at the latest /clock time and announce it (a simulator); False: wall time.
        report: where problems are said (a malformed message, a failed subscription); default stderr.

    Raises:
        MissingExtraError: the [foxglove] extra is not installed.
        FoxgloveError: the server could not listen there (the message names the address and what to do).
    """

    def __init__(
        self,
        host: str = DEFAULT_HOST,
        port: int = DEFAULT_PORT,
        *,
        sim_time: bool = True,
        report: Callable[[str], None] | None = None,
    ) -> None:
        foxglove = require_foxglove()
        from foxglove.websocket import Capability

        self.host = host
        self.sim_time = sim_time
        self._report = report or (lambda text: print(text, file=sys.stderr, flush=True))
        self._sdk = foxglove
        self._context = foxglove.Context()
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._topics: list[_Topic] = []
        self._by_channel: dict[int, _Topic] = {}
        self._clock: _Topic | None = None
        self._clock_ns: int | None = None
        self._clock_subscribed: float | None = None  # when /clock was subscribed (monotonic)
        self._last_time_sent = 0.0
        self._stopping = False
        self._background: Any = None
        self._worker: threading.Thread | None = None
        self._warned: set[str] = set()
        try:
            self._server = foxglove.start_server(
                name="tb4",
                host=host,
                port=port,
                context=self._context,
                server_listener=_Listener(self),
                capabilities=[Capability.Time] if sim_time else [],
                message_backlog_size=BACKLOG,
            )
        except RuntimeError as exc:
            raise FoxgloveError(_bind_problem(host, port, exc)) from None
        self.port: int = int(self._server.port)

    # --- what the user is told --------------------------------------------------------------------------------
    @property
    def url(self) -> str:
        """The WebSocket URL to open in the Foxglove app (Open connection, Foxglove WebSocket)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    @property
    def app_url(self) -> str | None:
        """A Foxglove web app link that opens this server as its data source (None once stopped)."""
        url = self._server.app_url()
        return None if url is None else str(url)

    @property
    def counts(self) -> dict[str, int]:
        """Messages sent so far on each topic's channel."""
        with self._lock:
            return {topic.full: topic.sent for topic in self._topics}

    # --- serving ----------------------------------------------------------------------------------------------
    def serve(self, namespace: str | Sequence[str] = "") -> None:
        """Advertise every served topic of these robots and start forwarding what clients subscribe to.

        Args:
            namespace: the robot's namespace, or a fleet's list of them (every robot's topics, /clock once).
        """
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from tb4.ros.background import BackgroundNode
        from tb4.ros.qos import LATEST, SENSOR

        namespaces = [namespace] if isinstance(namespace, str) else list(namespace) or [""]
        self._background = BackgroundNode(
            "tb4_foxglove", namespaces[0] if len(namespaces) == 1 else "", signal_handlers=False, events_executor=True
        )
        schemas: dict[str, Any] = {}
        seen: set[str] = set()
        for ns in (text.strip("/") for text in namespaces):
            for topic, type_name, kind in SERVED_TOPICS:
                full = _full_name(topic, ns)
                if full in seen:
                    continue  # /clock: one per process
                seen.add(full)
                package, _, name = type_name.split("/")
                keep = KEEP.get(topic, 1)
                latched = QoSProfile(
                    depth=keep, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
                )
                served = _Topic(
                    name=topic if len(namespaces) == 1 else full,
                    full=full,
                    msg_type=getattr(importlib.import_module(f"{package}.msg"), name),
                    qos={"sensor": SENSOR, "latched": latched}.get(kind, LATEST),
                    latched=kind == "latched",
                    keep=keep,
                    period=0.0 if topic in UNTHROTTLED else HEAVY_TYPES.get(type_name, PERIOD),
                )
                served.channels.append((self._channel(full, type_name, schemas), None))
                if topic in DERIVED_TOPICS:
                    derived, derived_type, cut = DERIVED_TOPICS[topic]
                    served.channels.append((self._channel(_full_name(derived, ns), derived_type, schemas), cut))
                if topic == "/clock":
                    self._clock = served
                self._topics.append(served)
        with self._lock:
            for served in self._topics:
                for channel, _ in served.channels:
                    self._by_channel[int(channel.id())] = served
        self._background.start()
        self._worker = threading.Thread(target=self._work, name="tb4_foxglove_worker", daemon=True)
        self._worker.start()

    def _channel(self, topic: str, type_name: str, schemas: dict[str, Any]) -> Any:
        if type_name not in schemas:
            text = message_definition(type_name).encode()
            schemas[type_name] = self._sdk.Schema(name=type_name, encoding="ros2msg", data=text)
        return self._sdk.Channel(topic, schema=schemas[type_name], message_encoding="cdr", context=self._context)

    def close(self) -> None:
        """Stop the server (clients are disconnected), the worker and the node."""
        with self._wake:
            self._stopping = True
            self._wake.notify_all()
        if self._worker is not None:
            self._worker.join(timeout=5.0)
        self._server.stop()
        if self._background is not None:
            self._background.close()
            self._background = None
        for served in self._topics:
            for channel, _ in served.channels:
                channel.close()

    # --- the server's threads ---------------------------------------------------------------------------------
    def _subscribed(self, channel_id: int, change: int) -> None:
        with self._wake:
            served = self._by_channel.get(channel_id)
            if served is None or self._stopping:
                return
            served.wanted = max(0, served.wanted + change)
            if change > 0 and served.latched and served.subscription is not None:
                served.resend = True  # the DDS subscription delivered its latched messages long ago
            if served.wanted == 0:
                served.unwanted_since = time.monotonic()
            self._wake.notify()

    # --- the node's thread --------------------------------------------------------------------------------------
    def _received(self, served: _Topic, data: bytes) -> None:
        if served is self._clock:
            self._tick(data)
        now = time.monotonic()
        with self._lock:
            if served.latched and data not in served.kept:
                served.kept.append(data)
                while len(served.kept) > served.keep:
                    served.kept.popleft()
            if self._before_clock(served):  # sent at the first clock: the kept ones of a latched topic, else this
                if served.latched:
                    served.resend = True
                else:
                    served.held = data
                return
            if now < served.next_send:
                if served.held is None:
                    self._wake.notify()
                served.held = data
                return
            served.next_send = now + served.period
        self._send(served, data)

    def _tick(self, data: bytes) -> None:
        nanoseconds = _clock_nanoseconds(data)
        if nanoseconds is None:
            return
        if self._clock_ns is None:
            with self._wake:
                self._clock_ns = nanoseconds
                self._wake.notify()  # the messages held for a first time are due now
        self._clock_ns = nanoseconds
        now = time.monotonic()
        if now - self._last_time_sent >= TIME_PERIOD:
            self._last_time_sent = now
            self._server.broadcast_time(nanoseconds)

    def _before_clock(self, served: _Topic) -> bool:
        """Whether a message of `served` must wait for the first /clock (sim time, none yet; under the lock)."""
        return self.sim_time and self._clock_ns is None and served is not self._clock

    def _send(self, served: _Topic, data: bytes) -> None:
        # never logged before the first clock with sim time (_received and _due hold it), so never at time zero
        log_time = (self._clock_ns or 0) if self.sim_time else time.time_ns()
        for channel, cut in served.channels:
            if cut is None:
                channel.log(data, log_time=log_time)
                continue
            try:
                channel.log(cut(data), log_time=log_time)
            except CdrError as exc:
                served.bad += 1
                self._warn_once(channel.topic(), f"tb4 foxglove: {channel.topic()} not sent: {exc}")
        served.sent += 1

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self._report(text)

    # --- the worker: subscriptions, re-sends, held messages -------------------------------------------------------
    def _work(self) -> None:
        while True:
            with self._wake:
                if self._stopping:
                    return
                self._wake.wait(timeout=self._next_wake())
                if self._stopping:
                    return
                now = time.monotonic()
                changes = self._subscription_changes(now)
                due = self._due(now)
                clock_late = self._clock_late(now)
            if clock_late:
                self._warn_once(
                    "clock",
                    f"tb4 foxglove: no /clock from the simulator within {CLOCK_WARN:.0f} s: "
                    "messages wait for its first one (they are logged at sim time)",
                )
            try:
                self._apply(changes)
                for served, data in due:
                    self._send(served, data)
            except Exception as exc:  # noqa: BLE001 - the simulator keeps running; say what failed, once
                self._warn_once(f"worker:{type(exc).__name__}", f"tb4 foxglove: {type(exc).__name__}: {exc}")
                time.sleep(0.1)

    def _next_wake(self) -> float:
        """Wall seconds until the earliest held message or lingering subscription is due (under the lock)."""
        now = time.monotonic()
        waits = [IDLE_WAKE]
        for served in self._topics:
            if not self._before_clock(served):  # else held for the first clock, which wakes the worker
                if served.held is not None:
                    waits.append(served.next_send - now)
                if served.resend:
                    waits.append(served.last_resend + RESEND_PERIOD - now)
            if served.subscription is not None and not self._wants(served):
                waits.append(served.unwanted_since + LINGER - now)
        if self._clock_subscribed is not None and self._clock_ns is None and "clock" not in self._warned:
            waits.append(self._clock_subscribed + CLOCK_WARN - now)
        return max(0.0, min(waits))

    def _clock_late(self, now: float) -> bool:
        """Whether the first /clock is overdue (sim time): subscribed CLOCK_WARN s ago and none yet."""
        if not self.sim_time or self._clock_ns is not None or self._clock_subscribed is None:
            return False
        return now - self._clock_subscribed >= CLOCK_WARN

    def _wants(self, served: _Topic) -> bool:
        """Whether a topic should be subscribed: a client wants it, or (/clock with sim time) anything."""
        if served.wanted > 0:
            return True
        return served is self._clock and self.sim_time and any(t.wanted > 0 for t in self._topics)

    def _subscription_changes(self, now: float) -> list[tuple[_Topic, bool]]:
        changes = []
        for served in self._topics:
            wanted = self._wants(served)
            if wanted and served.subscription is None:
                changes.append((served, True))
            elif not wanted and served.subscription is not None and now - served.unwanted_since >= LINGER:
                changes.append((served, False))
        return changes

    def _due(self, now: float) -> list[tuple[_Topic, bytes]]:
        due = []
        for served in self._topics:
            if self._before_clock(served):
                continue  # held until the first clock
            if served.held is not None and now >= served.next_send:
                due.append((served, served.held))
                served.held = None
                served.next_send = now + served.period
            if served.resend and now - served.last_resend >= RESEND_PERIOD:
                served.resend = False
                served.last_resend = now
                due.extend((served, data) for data in served.kept)
        return due

    def _apply(self, changes: list[tuple[_Topic, bool]]) -> None:
        if not changes:
            return
        node = self._background.node
        with self._background.paused():
            for served, subscribe in changes:
                if subscribe:
                    if served is self._clock and self._clock_subscribed is None:
                        self._clock_subscribed = time.monotonic()
                    served.subscription = node.create_subscription(
                        served.msg_type,
                        served.name,
                        lambda data, t=served: self._received(t, data),
                        served.qos,
                        raw=True,
                    )
                else:
                    node.destroy_subscription(served.subscription)
                    served.subscription = None
                    with self._lock:
                        served.held = None


def _full_name(topic: str, namespace: str) -> str:
    """A served topic's channel name: absolute topics as they are, the others under the robot's namespace."""
    return topic if topic.startswith("/") else f"/{namespace}/{topic}" if namespace else f"/{topic}"


def _bind_problem(host: str, port: int, exc: Exception) -> str:
    """The SDK's bind error in words a user can act on."""
    text = str(exc)
    if "in use" in text:
        return (
            f"port {port} on {host} is in use (another Foxglove server, the viewer or `tb4 sim`?): "
            "give another one with --foxglove PORT, or 0 for any free port"
        )
    if "lookup" in text or "resolve" in text or "Name or service" in text:
        return f"cannot listen on {host!r}: no such address ({text})"
    return f"cannot listen on {host}:{port}: {text}"
