"""Recording a run's ROS topics to MCAP (ROS 2 encoding), the format Foxglove and `ros2 bag` read.

Messages are taken serialized (raw CDR) straight off DDS and written with the `mcap` library; each channel's
schema is the full ros2msg definition (the type's .msg text plus its dependencies), as rosbag2 writes it.

A recording says what it missed (RecordingReport, also kept in the file as the `tb4_recording` metadata). Each DDS
writer numbers its messages from 1, and every message arrives with its number and its writer's id: a gap in one
writer's numbers is a message lost on the way. What no gap shows (a message published before the recorder matched a
writer, or after the last one it received) comes from the publishing process's own counts: the simulator keeps them
(PublicationLedger), with when each writer sent its first message (a writer that began after the recording did owes
it every message, so one lost before the first received is a loss too), and writes them into its run record, and
it holds its shutdown, bounded, until every recorder
reading its reliable topics has acknowledged every message. The reliable topics are read with KEEP_ALL, so a burst
(tf at --rate max) waits in the reader's queue instead of pushing older messages out; what is still lost there is
reported loudly. The best-effort topics (sensor data: odom, scan, battery, dock status, ground truth) drop messages
by design, as sensor streams do on a real robot: their drops are counted, never promised away.
"""

from __future__ import annotations

import contextlib
import json
import re
import threading
import time
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tb4.rosenv import share_directories

__all__ = [
    "LATCHED_DRAIN",
    "McapRecorder",
    "PublicationLedger",
    "RECORDED_TOPICS",
    "RecordingReport",
    "STARTUP_TOPICS",
    "message_definition",
    "ledger_in_record",
    "recorded_topics",
]

# (topic, type, qos) — qos: "sensor" (best effort), "latched" (transient local), "default".
RECORDED_TOPICS: tuple[tuple[str, str, str], ...] = (
    ("map", "nav_msgs/msg/OccupancyGrid", "latched"),
    ("odom", "nav_msgs/msg/Odometry", "sensor"),
    ("tf", "tf2_msgs/msg/TFMessage", "default"),
    ("tf_static", "tf2_msgs/msg/TFMessage", "latched"),
    ("scan", "sensor_msgs/msg/LaserScan", "sensor"),
    ("plan", "nav_msgs/msg/Path", "default"),
    ("battery_state", "sensor_msgs/msg/BatteryState", "sensor"),
    ("dock_status", "irobot_create_msgs/msg/DockStatus", "sensor"),
    ("amcl_pose", "geometry_msgs/msg/PoseWithCovarianceStamped", "latched"),
    ("ground_truth", "nav_msgs/msg/Odometry", "sensor"),  # the simulator's true pose, to plot amcl_pose against
    ("initialpose", "geometry_msgs/msg/PoseWithCovarianceStamped", "default"),
    ("goals", "nav_msgs/msg/Goals", "latched"),
    ("/clock", "rosgraph_msgs/msg/Clock", "default"),
)

# Latched topics a running simulator (or robot) has published before any mission starts: a recording without them
# cannot be replayed (no map, no sensor frames), so a run waits for them before its first command.
STARTUP_TOPICS = ("map", "tf_static")
# wall seconds close() waits for messages it knows are on their way: a latched topic's message from a writer it has
# matched, or a writer's messages up to the last one its publisher counted
LATCHED_DRAIN = 5.0
# the nodes whose readers a publishing process waits for at its shutdown (ours, and `ros2 bag record`'s)
RECORDER_NODES = ("tb4_recorder", "rosbag2_recorder")
METADATA_NAME = "tb4_recording"  # the MCAP metadata record holding the RecordingReport

_PRIMITIVES = {
    "bool",
    "byte",
    "char",
    "float32",
    "float64",
    "int8",
    "uint8",
    "int16",
    "uint16",
    "int32",
    "uint32",
    "int64",
    "uint64",
    "string",
    "wstring",
}


def _msg_text(package: str, name: str) -> str:
    shares = share_directories()
    for share in shares:
        path = share / package / "msg" / f"{name}.msg"
        if path.is_file():
            return path.read_text(encoding="utf-8")
    raise FileNotFoundError(f"no definition for {package}/msg/{name} under {', '.join(map(str, shares))}")


def _dependencies(package: str, text: str) -> list[tuple[str, str]]:
    found = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line or "=" in line.split()[0]:
            continue
        field_type = re.sub(r"\[.*?\]$", "", line.split()[0])
        field_type = re.sub(r"<=\d+$", "", field_type)
        if field_type in _PRIMITIVES or field_type.startswith(("string<", "wstring<")):
            continue
        if "/" in field_type:
            parts = field_type.split("/")
            found.append((parts[0], parts[-1]))
        elif "=" not in line:
            found.append((package, field_type))
    return found


def message_definition(type_name: str) -> str:
    """rosbag2-style full definition: the type's text, then each dependency once after a separator line."""
    package, _, name = type_name.split("/")
    main = _msg_text(package, name)
    parts = [main.rstrip("\n")]
    seen: set[tuple[str, str]] = set()
    queue = _dependencies(package, main)
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = _msg_text(*dep)
        parts.append("=" * 80 + f"\nMSG: {dep[0]}/{dep[1]}\n" + text.rstrip("\n"))
        queue.extend(_dependencies(dep[0], text))
    return "\n".join(parts) + "\n"


def recorded_topics(namespaces: str | Sequence[str] = "") -> dict[str, str]:
    """Every recorded topic's full name under `namespaces` (a robot's, or a fleet's list) and its QoS kind; the one
    /clock once."""
    spaces = [namespaces] if isinstance(namespaces, str) else list(namespaces) or [""]
    topics: dict[str, str] = {}
    for ns in (text.strip("/") for text in spaces):
        for topic, _type_name, kind in RECORDED_TOPICS:
            full = topic if topic.startswith("/") else f"/{ns}/{topic}" if ns else f"/{topic}"
            topics.setdefault(full, kind)
    return topics


def _writer_key(gid: Any) -> str:
    """A DDS writer's id as text: the 16 bytes of its GUID (what a message's `publisher_gid` and the graph's
    `endpoint_gid` both hold, the latter maybe padded)."""
    return bytes(gid)[:16].hex()


#: The writer key of messages whose writer's id the middleware does not give (rclpy 7, ROS 2 Jazzy, has no
#: publisher_gid in a message's info).
_UNKNOWN_WRITER = ""


def _sequence_number(info: Mapping[str, Any]) -> tuple[str, int] | None:
    """(writer, its number for this message) from a message's info; None from a middleware that numbers nothing."""
    number = info.get("publication_sequence_number")
    gid = info.get("publisher_gid")
    if not isinstance(number, int) or not 0 < number < 2**63 or not gid:
        return None
    return _writer_key(gid["data"]), number


def ledger_in_record(
    record_path: Path,
) -> tuple[dict[str, dict[str, int]] | None, dict[str, dict[str, int]] | None]:
    """What a simulator's PublicationLedger wrote into its run record, read once: the publication counts
    (`summary.published`, PublicationLedger.snapshot) and when each writer sent its first message
    (`summary.first_sent_ns`, PublicationLedger.first_sent).

    Returns:
        (counts, first sent), each None when the file or its section is missing or not a mapping.
    """
    try:
        summary = json.loads(Path(record_path).read_text(encoding="utf-8"))["summary"]
    except (OSError, ValueError, KeyError, TypeError):
        return None, None
    if not isinstance(summary, dict):
        return None, None
    published, first_sent = summary.get("published"), summary.get("first_sent_ns")
    return (
        published if isinstance(published, dict) else None,
        first_sent if isinstance(first_sent, dict) else None,
    )


@dataclass
class RecordingReport:
    """What a recording holds and what it missed, per topic (full names).

    Attributes:
        path: the MCAP file.
        recorded: messages written, per topic.
        missed: reliable topics (latched and default): messages published but not recorded. Empty when complete.
        dropped: best-effort topics: messages dropped on the way, by design for sensor data.
        against_publisher: whether the publisher's own counts were compared (else only the gaps in each writer's
            sequence numbers: a message lost before a writer's first or after its last one received goes unseen;
            with the counts, one lost before the first received goes unseen only from a writer that had sent
            messages before the recording began).
    """

    path: Path
    recorded: dict[str, int]
    missed: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    against_publisher: bool = False

    @property
    def complete(self) -> bool:
        """True when no reliable topic lost a message."""
        return not self.missed

    def warning(self) -> str | None:
        """One line naming each reliable topic that lost messages and how many; None for a complete recording."""
        if not self.missed:
            return None
        lost = ", ".join(
            f"{topic} {count} of {count + self.recorded.get(topic, 0)}" for topic, count in sorted(self.missed.items())
        )
        return f"the recording {self.path} is incomplete: messages published but not recorded: {lost}"

    def to_dict(self) -> dict[str, Any]:
        """The report as the run record's `recording` section."""
        return {
            "path": str(self.path),
            "complete": self.complete,
            "checked": "publisher counts and sequence numbers" if self.against_publisher else "sequence numbers",
            "recorded": dict(sorted(self.recorded.items())),
            "missed": dict(sorted(self.missed.items())),
            "dropped_best_effort": dict(sorted(self.dropped.items())),
        }


@dataclass
class _WriterLog:
    """The sequence numbers received from one writer: the lowest, the highest, and how many."""

    first: int
    last: int
    received: int = 1


class PublicationLedger:
    """What a publishing process (the simulator) sent on the recorded topics, and what it took there from other
    writers: each DDS writer's last sequence number per topic, for a recording to be checked against.

    A writer numbers its messages from 1, so the count of its publish() calls is its last number. The count starts
    as each publisher is made (`counting`), as some send their first message in their constructor (the latched map
    and static transforms). Messages the process takes from others (a mission's `initialpose`) are counted by the
    highest number taken from each writer (`watch_subscriptions`). The ledger also keeps when each writer sent its
    first message (`first_sent`): a recording that began before then owes that writer every message, the first ones
    too, and a loss among those shows as no gap in the numbers a recorder received."""

    def __init__(self, namespaces: str | Sequence[str] = "") -> None:
        """An empty ledger of the recorded topics under `namespaces`.

        Args:
            namespaces: the robot's namespace, or a fleet's (every robot's topics, the one /clock once).
        """
        self.topics = recorded_topics(namespaces)
        self._lock = threading.Lock()
        self._last: dict[str, dict[str, int]] = {}
        self._first_sent: dict[str, dict[str, int]] = {}  # topic -> writer -> wall ns of its first message
        self._publishers: list[tuple[str, Any, Any]] = []  # (topic, publisher, its node)

    @contextlib.contextmanager
    def counting(self, node_class: type) -> Iterator[PublicationLedger]:
        """Within the block, every publisher a `node_class` node makes on a recorded topic is counted.

        Args:
            node_class: the class of the process's nodes (the simulator's SimNode).

        Yields:
            This ledger.
        """
        own = node_class.__dict__.get("create_publisher")
        create = node_class.create_publisher  # type: ignore[attr-defined]
        ledger = self

        def create_publisher(node: Any, *args: Any, **kwargs: Any) -> Any:
            publisher = create(node, *args, **kwargs)
            ledger._count(node, publisher)
            return publisher

        setattr(node_class, "create_publisher", create_publisher)  # noqa: B010 - a method, assigned for the block
        try:
            yield self
        finally:
            if own is None:
                delattr(node_class, "create_publisher")
            else:
                setattr(node_class, "create_publisher", own)  # noqa: B010

    def _count(self, node: Any, publisher: Any) -> None:
        topic = publisher.topic_name
        if topic not in self.topics:
            return
        with self._lock:
            taken = self._last.setdefault(topic, {})
            ours = [
                key
                for info in node.get_publishers_info_by_topic(topic)
                if info.node_name == node.get_name()
                and info.node_namespace == node.get_namespace()
                and (key := _writer_key(info.endpoint_gid)) not in taken
            ]
            if len(ours) != 1:  # not in the graph, or not told apart from another of this node's: not counted
                return
            key = ours[0]
            taken[key] = 0
            first_sent = self._first_sent.setdefault(topic, {})
        send = publisher.publish

        def publish(msg: Any) -> None:
            if key not in first_sent:  # the time before the send: a recorder that began before it owes the message
                with self._lock:
                    first_sent.setdefault(key, time.time_ns())
            send(msg)
            with self._lock:
                taken[key] += 1

        publisher.publish = publish
        self._publishers.append((topic, publisher, node))

    def watch_subscriptions(self, nodes: Iterable[Any]) -> None:
        """Count what these nodes take on recorded topics that the process does not publish itself: the highest
        sequence number taken from each writer.

        Args:
            nodes: the process's nodes, once their subscriptions are made.
        """
        from rclpy.subscription import Subscription

        for node in nodes:
            for subscription in list(node.subscriptions):
                topic = subscription.topic_name
                if topic not in self.topics or any(topic == own for own, _, _ in self._publishers):
                    continue
                callback = subscription.callback
                with_info = subscription._callback_type is Subscription.CallbackType.WithMessageInfo

                def taken(
                    msg: Any, info: Any, callback: Any = callback, with_info: bool = with_info, topic: str = topic
                ) -> None:
                    self._took(topic, info)
                    if with_info:
                        callback(msg, info)
                    else:
                        callback(msg)

                subscription.callback = taken

    def _took(self, topic: str, info: Mapping[str, Any]) -> None:
        numbered = _sequence_number(info)
        if numbered is None:
            number = info.get("publication_sequence_number")
            if not isinstance(number, int) or not 0 < number < 2**63:
                return
            numbered = _UNKNOWN_WRITER, number  # rclpy 7 (Jazzy) gives no writer id: numbered all the same
        key, number = numbered
        sent = info.get("source_timestamp")
        with self._lock:
            writers = self._last.setdefault(topic, {})
            writers[key] = max(writers.get(key, 0), number)
            if number == 1 and isinstance(sent, int) and sent > 0:  # its first message's time, as its writer stamped it
                self._first_sent.setdefault(topic, {})[key] = sent

    def snapshot(self) -> dict[str, dict[str, int]]:
        """{topic: {writer: its last sequence number}}: what a recording of this process's topics must reach."""
        with self._lock:
            return {topic: dict(writers) for topic, writers in self._last.items() if writers}

    def first_sent(self) -> dict[str, dict[str, int]]:
        """{topic: {writer: when it sent its first message, wall clock ns}}: a recording that began before owes that
        writer all its messages. A writer whose first message this process did not see (one taken from another
        process from its second on) is left out."""
        with self._lock:
            return {topic: dict(writers) for topic, writers in self._first_sent.items() if writers}

    def wait_for_delivery(self, timeout: float) -> list[str]:
        """Wait (at most `timeout` wall seconds) until each reliable recorded topic that a recorder reads has
        matched every compatible reader the graph shows and has every message acknowledged: a message sent just
        before the process stops, or a latched one whose writer matched the recorder late, is then in the
        recorder's queue before the writer goes. Call it once nothing publishes any more.

        Returns:
            The topics whose messages were not all acknowledged in time.
        """
        from rclpy.duration import Duration

        from tb4.core.waits import Deadline, wait_until
        from tb4.ros.qos import serves

        deadline = Deadline(timeout)
        late = []
        for topic, publisher, node in self._publishers:
            if self.topics[topic] == "sensor":
                continue  # read best effort: nothing is acknowledged
            readers = node.get_subscriptions_info_by_topic(topic)
            if not any(info.node_name in RECORDER_NODES for info in readers):
                continue
            wanted = sum(serves(publisher.qos_profile, info.qos_profile) for info in readers)

            def all_matched(publisher: Any = publisher, wanted: int = wanted) -> bool:
                return bool(publisher.get_subscription_count() >= wanted)

            matched = wait_until(all_matched, deadline.remaining())
            acked = publisher.wait_for_all_acked(Duration(nanoseconds=int(deadline.remaining() * 1e9)))
            if not (matched and acked):
                late.append(topic)
        return late


class McapRecorder:
    """Subscribes (raw) to the run's topics in its own rclpy context and writes every message as it arrives."""

    def __init__(self, path: Path, namespace: str | Sequence[str] = "", signal_handlers: bool = True) -> None:
        """`namespace`: the robot's, or a fleet's list of them (every robot's topics, the one /clock once).
        `signal_handlers`: rclpy's, which shut the recorder's context on Ctrl-C; a process that handles its signals
        itself (the simulator) closes the recorder in its own time instead."""
        import importlib

        from mcap.writer import CompressionType, Writer
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

        from tb4.ros.background import BackgroundNode

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="turtlebot4-navigator")
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self._writers: dict[str, dict[str, _WriterLog]] = {}  # topic -> writer -> the numbers received from it
        # topic -> the numbers of messages that came without their writer's id (rclpy 7, ROS 2 Jazzy, gives none)
        self._unattributed: dict[str, _WriterLog] = {}
        self._present: dict[str, set[str]] | None = None  # the writers of each topic when the recording began
        self._started_ns: int | None = None  # when the recording began (wall clock), once its writers were matched
        self._report_made: RecordingReport | None = None  # once closed
        namespaces = [namespace] if isinstance(namespace, str) else list(namespace) or [""]
        self._background = BackgroundNode(
            "tb4_recorder", namespaces[0] if len(namespaces) == 1 else "", signal_handlers=signal_handlers
        )
        self.node = self._background.node
        # KEEP_ALL: a burst (tf at --rate max, while this thread waits for the interpreter) queues instead of
        # pushing older messages out of a depth-limited reader queue
        keep_all, reliable = HistoryPolicy.KEEP_ALL, ReliabilityPolicy.RELIABLE
        qos = {
            "sensor": qos_profile_sensor_data,
            "latched": QoSProfile(history=keep_all, reliability=reliable, durability=DurabilityPolicy.TRANSIENT_LOCAL),
            "default": QoSProfile(history=keep_all, reliability=reliable),
        }
        schemas: dict[str, int] = {}
        self._startup: list[str] = []
        self._subscribed: list[tuple[str, str, str, Any]] = []  # (topic as subscribed, full name, kind, subscription)
        self._kinds: dict[str, str] = {}  # full name -> kind
        for ns in (text.strip("/") for text in namespaces):
            for topic, type_name, kind in RECORDED_TOPICS:
                full = topic if topic.startswith("/") else f"/{ns}/{topic}" if ns else f"/{topic}"
                if full in self.counts:
                    continue  # /clock: one per process, recorded once
                package, _, name = type_name.split("/")
                msg_type = getattr(importlib.import_module(f"{package}.msg"), name)
                if type_name not in schemas:
                    text = message_definition(type_name).encode()
                    schemas[type_name] = self._writer.register_schema(type_name, "ros2msg", text)
                channel = self._writer.register_channel(full, "cdr", schemas[type_name])
                self.counts[full] = 0
                if topic in STARTUP_TOPICS:
                    self._startup.append(full)
                name_used = topic if len(namespaces) == 1 else full  # one robot: relative to the node's namespace
                subscription = self.node.create_subscription(
                    msg_type,
                    name_used,
                    lambda data, info, c=channel, t=full: self._write(c, t, data, info),
                    qos[kind],
                    raw=True,
                )
                self._subscribed.append((name_used, full, kind, subscription))
                self._kinds[full] = kind
        self._background.start()

    def wait_for_startup_topics(self, timeout: float) -> list[str]:
        """Wait (at most `timeout` wall seconds) until each STARTUP_TOPICS message is recorded and every reliable
        topic's writers are matched, then take the writers present as the recording's start (a writer that
        appears later has every message of its own in the run: one missing from its first is a loss).

        A large latched message (a map is hundreds of kB, sent in fragments) can arrive seconds after discovery on
        a loaded machine, and a run at --rate max may be over by then.

        Returns:
            The STARTUP_TOPICS still missing.
        """
        from tb4.core.waits import wait_until

        def missing() -> list[str]:
            with self._lock:
                return [topic for topic in self._startup if self.counts[topic] == 0]

        wait_until(lambda: not missing() and not self.unmatched(), timeout)
        self._started_ns = time.time_ns()
        self._present = {
            full: {_writer_key(info.endpoint_gid) for info in self.node.get_publishers_info_by_topic(name)}
            for name, full, _, _ in self._subscribed
        }
        return missing()

    def unmatched(self) -> list[str]:
        """The reliable topics with a compatible writer in the graph that this recorder's reader has not matched.

        Returns:
            Their full names: a message sent there now would not reach the recording (a latched one only later,
            maybe after the run).
        """
        from tb4.ros.qos import serves

        late = []
        for name, full, kind, subscription in self._subscribed:
            if kind == "sensor":
                continue
            writers = self.node.get_publishers_info_by_topic(name)
            wanted = sum(serves(info.qos_profile, subscription.qos_profile) for info in writers)
            if subscription.get_publisher_count() < wanted:
                late.append(full)
        return late

    def _write(self, channel: int, topic: str, data: Any, info: Mapping[str, Any]) -> None:
        now = time.time_ns()
        with self._lock:
            if self._file.closed:
                return
            sent = info.get("source_timestamp") or now
            self._writer.add_message(
                channel, log_time=now, data=bytes(data), publish_time=sent, sequence=self.counts[topic]
            )
            self.counts[topic] += 1
            numbered = _sequence_number(info)
            if numbered is None:
                self._note_unattributed(topic, info)
                return
            key, number = numbered
            writers = self._writers.setdefault(topic, {})
            log = writers.get(key)
            if log is None:
                writers[key] = _WriterLog(number, number)
            else:
                log.first, log.last, log.received = min(log.first, number), max(log.last, number), log.received + 1

    def _note_unattributed(self, topic: str, info: Mapping[str, Any]) -> None:
        number = info.get("publication_sequence_number")
        if not isinstance(number, int) or not 0 < number < 2**63:
            return
        log = self._unattributed.get(topic)
        if log is None:
            self._unattributed[topic] = _WriterLog(number, number)
        else:
            log.first, log.last, log.received = min(log.first, number), max(log.last, number), log.received + 1

    def _logs(self, topic: str, published: Mapping[str, Mapping[str, int]] | None) -> dict[str, _WriterLog]:
        """Each writer's numbers received on `topic`. Messages that came without their writer's id (rclpy 7) count as
        the one writer's when the publishing process, or else the graph, knows only one on the topic (the simulator
        is its topics' one writer); with more, they stay unattributed and the check reads them as not received."""
        logs = dict(self._writers.get(topic, {}))
        anonymous = self._unattributed.get(topic)
        writers = set((published or {}).get(topic, {}))
        if anonymous is not None:
            known = writers or set((self._present or {}).get(topic, set()))
            if len(known) == 1 and not logs:
                logs[known.pop()] = anonymous
        if writers == {_UNKNOWN_WRITER} and len(logs) == 1:  # the publishing process knew no writer id either
            logs = {_UNKNOWN_WRITER: next(iter(logs.values()))}
        return logs

    def _waiting(self, published: Mapping[str, Mapping[str, int]]) -> bool:
        """A message still on its way: a latched topic with a writer but nothing recorded (a run's goal, published
        once, from a writer that matched this reader on its own side of discovery, seconds after ours), or a writer
        recorded only up to below the last number its publisher counted (acknowledged, so in this reader's queue).
        A writer never received from on a volatile topic sent before it matched: nothing of that is coming."""
        with self._lock:
            empty = [name for name, full, kind, _ in self._subscribed if kind == "latched" and not self.counts[full]]
            behind = any(
                key in self._writers.get(topic, {}) and number > self._writers[topic][key].last
                for topic, writers in published.items()
                if self._kinds.get(topic, "sensor") != "sensor"
                for key, number in writers.items()
            )
        return behind or any(self.node.count_publishers(name) > 0 for name in empty)

    def close(
        self,
        published: Mapping[str, Mapping[str, int]] | None = None,
        timeout: float = LATCHED_DRAIN,
        first_sent: Mapping[str, Mapping[str, int]] | None = None,
    ) -> RecordingReport:
        """Wait (at most `timeout` wall seconds) for the messages on their way, end the recording and say what it
        missed.

        Args:
            published: the publishing process's counts (PublicationLedger.snapshot, or a simulator's run record
                through ledger_in_record); None: only the gaps in each writer's numbers are checked.
            timeout: wall seconds to wait for the messages known to be on their way.
            first_sent: when each of those writers sent its first message (PublicationLedger.first_sent, or
                ledger_in_record), on this machine's clock: a writer that began after the recording did owes
                it every message. Without it, a writer present at the start owes only what it sent from the first
                message received on.

        Returns:
            The RecordingReport (also written into the file as its `tb4_recording` metadata).
        """
        from tb4.core.waits import wait_until

        if self._report_made is not None:
            return self._report_made
        wait_until(lambda: not self._waiting(published or {}), timeout)
        self._background.close()
        with self._lock:
            report = self._report(published, first_sent or {})
            self._writer.add_metadata(
                METADATA_NAME, {key: json.dumps(value) for key, value in report.to_dict().items()}
            )
            self._writer.finish()
            self._file.close()
        self._report_made = report
        return report

    def _report(
        self, published: Mapping[str, Mapping[str, int]] | None, first_sent: Mapping[str, Mapping[str, int]]
    ) -> RecordingReport:
        report = RecordingReport(self.path, dict(self.counts), against_publisher=published is not None)
        for _, topic, kind, _ in self._subscribed:
            logs = self._logs(topic, published)
            present = self._present.get(topic) if self._present is not None else None
            began = first_sent.get(topic)
            began = began if isinstance(began, Mapping) else {}  # a run record's, maybe broken
            lost = 0
            for key, log in logs.items():
                lost += log.last - log.first + 1 - log.received  # a gap in its numbers
                if self._owed_all(key, present, began):
                    lost += log.first - 1  # sent after the recording began, lost before the first one received
            for key, last in (published or {}).get(topic, {}).items():
                received = logs.get(key)
                if not last:
                    continue
                if received is not None:
                    lost += max(0, last - received.last)  # sent after the last one recorded
                elif kind == "latched" and present is not None and not self._owed_all(key, present, began):
                    lost += 1  # its latest was due to any reader; the ones before the recording were not
                else:
                    lost += last
            if lost:
                (report.dropped if kind == "sensor" else report.missed)[topic] = lost
        return report

    def _owed_all(self, key: str, present: set[str] | None, first_sent: Mapping[str, int]) -> bool:
        """Whether every message of writer `key` was sent after the recording began: a writer of the run's own, or
        one present at the start whose first message came after it (a plan, a goal). Unknown (no start taken):
        no."""
        if present is None:
            return False
        sent = first_sent.get(key)
        began_after = self._started_ns is not None and isinstance(sent, int) and sent >= self._started_ns
        return key not in present or began_after
