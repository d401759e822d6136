"""Recording a run's ROS topics to MCAP (ROS 2 encoding), the format Foxglove and `ros2 bag` read.

Messages are taken serialized (raw CDR) straight off DDS and written with the `mcap` library; each channel's
schema is the full ros2msg definition (the type's .msg text plus its dependencies), as rosbag2 writes it.
"""

from __future__ import annotations

import re
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from tb4.rosenv import share_directories

__all__ = ["McapRecorder", "RECORDED_TOPICS", "STARTUP_TOPICS", "message_definition"]

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
LATCHED_DRAIN = 5.0  # wall seconds close() waits for a latched topic with a writer but no message yet (a run's goals)

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


class McapRecorder:
    """Subscribes (raw) to the run's topics in its own rclpy context and writes every message as it arrives."""

    def __init__(self, path: Path, namespace: str | Sequence[str] = "", signal_handlers: bool = True) -> None:
        """`namespace`: the robot's, or a fleet's list of them (every robot's topics, the one /clock once).
        `signal_handlers`: rclpy's, which shut the recorder's context on Ctrl-C; a process that handles its signals
        itself (the simulator) closes the recorder in its own time instead."""
        import importlib

        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

        from tb4.ros.background import BackgroundNode

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library="turtlebot4-navigator")
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}
        namespaces = [namespace] if isinstance(namespace, str) else list(namespace) or [""]
        self._background = BackgroundNode(
            "tb4_recorder", namespaces[0] if len(namespaces) == 1 else "", signal_handlers=signal_handlers
        )
        self.node = self._background.node
        qos = {
            "sensor": qos_profile_sensor_data,
            "latched": QoSProfile(
                depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
            ),
            "default": QoSProfile(depth=50),
        }
        schemas: dict[str, int] = {}
        self._startup: list[str] = []
        self._latched: list[tuple[str, Any]] = []  # (topic as subscribed, subscription)
        self._full_names: dict[str, str] = {}  # topic as subscribed -> its recorded (full) name
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
                    msg_type, name_used, lambda data, c=channel, t=full: self._write(c, t, data), qos[kind], raw=True
                )
                if kind == "latched":
                    self._latched.append((name_used, subscription))
                    self._full_names[name_used] = full
        self._background.start()

    def wait_for_startup_topics(self, timeout: float) -> list[str]:
        """Wait (at most `timeout` wall seconds) until each STARTUP_TOPICS message is recorded and every latched
        topic's writers are matched; the STARTUP_TOPICS still missing. A large latched message (a map is hundreds
        of kB, sent in fragments) can arrive seconds after discovery on a loaded machine, and a run at --rate max
        may be over by then."""
        from tb4.core.waits import wait_until

        def missing() -> list[str]:
            with self._lock:
                return [topic for topic in self._startup if self.counts[topic] == 0]

        def unmatched() -> bool:
            """A latched topic's writer not yet matched: a goal published once during a short run would be
            delivered only after the recording has closed."""
            return any(sub.get_publisher_count() < self.node.count_publishers(name) for name, sub in self._latched)

        wait_until(lambda: not missing() and not unmatched(), timeout)
        return missing()

    def _wait_for_latched(self, timeout: float) -> None:
        """Wait (at most `timeout` s) until every latched topic that has a writer has been recorded at least once. A
        writer matches our reader on its own side of discovery, which on a loaded machine can come seconds after
        ours; being latched, the message (a run's goal, published once) then still arrives, maybe after the run."""
        from tb4.core.waits import wait_until

        def waiting() -> bool:
            with self._lock:
                empty = [name for name, _ in self._latched if self.counts[self._full_names[name]] == 0]
            return any(self.node.count_publishers(name) > 0 for name in empty)

        wait_until(lambda: not waiting(), timeout)

    def _write(self, channel: int, topic: str, data: Any) -> None:
        now = time.time_ns()
        with self._lock:
            if self._file.closed:
                return
            self._writer.add_message(
                channel, log_time=now, data=bytes(data), publish_time=now, sequence=self.counts[topic]
            )
            self.counts[topic] += 1

    def close(self) -> dict[str, int]:
        self._wait_for_latched(LATCHED_DRAIN)
        self._background.close()
        with self._lock:
            self._writer.finish()
            self._file.close()
        return dict(self.counts)
