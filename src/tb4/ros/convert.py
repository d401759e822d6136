"""Conversions between ROS messages and the core's plain values ((x, y, yaw) tuples, float seconds, arrays).

A thin wrapper: the maths (quaternions, durations) is tb4.core.geometry's and tb4.core.units'; this only builds
and reads the messages.

The nav core reports feedback/results as dicts keyed by the Nav2 field names; `fill_message` turns such a dict
into the message by looking at each field's declared type, so no action needs a hand-written converter.
"""

from __future__ import annotations

import array
import math
import struct
import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Pose, PoseStamped, Quaternion
from nav_msgs.msg import OccupancyGrid, Path
from rclpy.serialization import serialize_message

from tb4.core import geometry
from tb4.core.maps import OccupancyMap
from tb4.core.units import from_sec_nanosec, seconds_of, to_sec_nanosec
from tb4.nav.costmap import Costmap2D
from tb4.wire import as_missed_waypoint

__all__ = [
    "yaw_to_quaternion",
    "quaternion_to_yaw",
    "pose_msg",
    "pose_stamped",
    "pose_to_tuple",
    "checked_pose",
    "duration_msg",
    "duration_to_seconds",
    "serialized_header_stamp",
    "StampedSerialization",
    "time_msg",
    "set_time",
    "set_yaw",
    "path_msg",
    "path_to_array",
    "occupancy_grid_msg",
    "costmap_to_occupancy_values",
    "fill_message",
    "goal_poses",
]


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """geometry_msgs/Quaternion of a heading (the maths: tb4.core.geometry)."""
    x, y, z, w = geometry.yaw_to_quaternion(yaw)
    return Quaternion(x=x, y=y, z=z, w=w)


def quaternion_to_yaw(q: Quaternion) -> float:
    """Heading of a geometry_msgs/Quaternion (the maths: tb4.core.geometry)."""
    return geometry.quaternion_to_yaw(q.x, q.y, q.z, q.w)


def pose_msg(x: float, y: float, yaw: float) -> Pose:
    pose = Pose()
    pose.position.x = float(x)
    pose.position.y = float(y)
    pose.orientation = yaw_to_quaternion(float(yaw))
    return pose


def time_msg(seconds: float) -> Time:
    sec, nanosec = to_sec_nanosec(seconds)
    return Time(sec=sec, nanosec=nanosec)


def set_time(stamp: Time, seconds: float) -> None:
    """Write `seconds` into an existing Time: publishers reuse one message instead of building one per publish."""
    stamp.sec, stamp.nanosec = to_sec_nanosec(seconds)


def set_yaw(q: Quaternion, yaw: float) -> None:
    """Write a yaw rotation into an existing Quaternion (same values as yaw_to_quaternion)."""
    q.x, q.y, q.z, q.w = geometry.yaw_to_quaternion(yaw)


def pose_stamped(pose: Sequence[float], stamp: float = 0.0, frame_id: str = "map") -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = frame_id
    msg.header.stamp = time_msg(stamp)
    msg.pose = pose_msg(pose[0], pose[1], pose[2])
    return msg


def pose_to_tuple(msg: Pose | PoseStamped) -> tuple[float, float, float]:
    pose = msg.pose if isinstance(msg, PoseStamped) else msg
    return (float(pose.position.x), float(pose.position.y), quaternion_to_yaw(pose.orientation))


def checked_pose(msg: Pose | PoseStamped, what: str = "pose") -> tuple[float, float, float]:
    """(x, y, yaw) of a pose, or ValueError naming what is wrong (NaN/inf, zero quaternion, wrong frame)."""
    pose = msg.pose if isinstance(msg, PoseStamped) else msg
    p, q = pose.position, pose.orientation
    values = (p.x, p.y, p.z, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what} has a non-finite coordinate or orientation")
    if q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w < 1e-12:
        raise ValueError(f"{what} has a zero quaternion")
    if isinstance(msg, PoseStamped) and msg.header.frame_id not in ("", "map"):
        raise ValueError(f"{what} is in frame '{msg.header.frame_id}'; only 'map' is supported")
    return pose_to_tuple(pose)


def duration_msg(seconds: float) -> Duration:
    sec, nanosec = to_sec_nanosec(seconds)
    return Duration(sec=sec, nanosec=nanosec)


def duration_to_seconds(msg: Duration | Time) -> float:
    """Float seconds of a Duration or a Time stamp."""
    return seconds_of(msg)


def serialized_header_stamp(data: bytes) -> float:
    """Seconds of header.stamp of a serialized (CDR) message whose first field is a std_msgs/Header, read without
    deserializing the rest: a watcher of a fast topic (raw=True) needs every stamp but few whole messages.

    After the 4-byte encapsulation (its second byte: 1 little-endian, 0 big-endian), stamp.sec (int32) and
    stamp.nanosec (uint32) open the payload."""
    if len(data) < 12:
        raise ValueError(f"a serialized stamped message has at least 12 bytes, got {len(data)}")
    sec, nanosec = struct.unpack_from("<iI" if data[1] & 1 else ">iI", data, 4)
    return from_sec_nanosec(sec, nanosec)


class StampedSerialization:
    """One stamped message a publisher sends again and again, mostly unchanged but for its stamp (a robot on the
    dock: its ground truth, dock status and amcl_pose): its serialized bytes are kept, and when the content is
    the same as last time only the 8 bytes of header.stamp are rewritten, so the message is neither refilled
    nor serialized again. What `publish(bytes)` sends decodes to exactly what `publish(msg)` would send (the
    values are the same bytes; only CDR's alignment padding, which no reader looks at, is left as it was).

    `serialized(now, key, fill)`: the bytes of the message stamped `now`. `fill(msg)` writes its content; it runs
    when `key` (bytes packed from that content, bit-exact: -0.0 is not 0.0) differs from the last call's. Every
    other field must stay as set before the first call. Safe from several threads."""

    def __init__(self, msg: Any) -> None:
        self.msg = msg
        self._key: bytes | None = None
        self._data = bytearray()
        self._stamp_format = "<iI"
        self._lock = threading.Lock()

    def repeats(self, key: bytes) -> bool:
        """Whether a message with content `key` would say again what the last one said (only its stamp new)."""
        with self._lock:
            return key == self._key

    def serialized(self, now: float, key: bytes, fill: Callable[[Any], None]) -> bytes:
        sec, nanosec = to_sec_nanosec(now)
        with self._lock:
            if key != self._key:
                fill(self.msg)
                self.msg.header.stamp.sec, self.msg.header.stamp.nanosec = sec, nanosec
                self._data = bytearray(serialize_message(self.msg))
                self._stamp_format = "<iI" if self._data[1] & 1 else ">iI"  # as serialized_header_stamp reads it
                self._key = key
            else:
                struct.pack_into(self._stamp_format, self._data, 4, sec, nanosec)
            return bytes(self._data)


def path_msg(path: np.ndarray | Sequence[Sequence[float]], stamp: float = 0.0, frame_id: str = "map") -> Path:
    msg = Path()
    msg.header.frame_id = frame_id
    msg.header.stamp = time_msg(stamp)
    msg.poses = [pose_stamped(p.tolist(), stamp, frame_id) for p in np.asarray(path, dtype=float).reshape(-1, 3)]
    return msg


def path_to_array(msg: Path) -> np.ndarray:
    if not msg.poses:
        return np.zeros((0, 3))
    return np.array([pose_to_tuple(p) for p in msg.poses], dtype=float)


def occupancy_grid_msg(grid: OccupancyMap, stamp: float = 0.0, frame_id: str = "map") -> OccupancyGrid:
    msg = OccupancyGrid()
    msg.header.frame_id = frame_id
    msg.header.stamp = time_msg(stamp)
    msg.info.map_load_time = time_msg(stamp)
    msg.info.resolution = float(grid.resolution)
    msg.info.width = grid.width
    msg.info.height = grid.height
    msg.info.origin = pose_msg(grid.origin_x, grid.origin_y, grid.origin_yaw)
    data = array.array("b")  # an array.array skips the generated setter's per-element checks
    data.frombytes(np.ascontiguousarray(grid.data, dtype=np.int8).tobytes())
    msg.data = data
    return msg


# Nav2's costmap publisher translation: 0 free, 1..252 -> 1..98, 253 inscribed -> 99, 254 lethal -> 100, 255 -> -1.
_COST_TO_OCCUPANCY = np.zeros(256, dtype=np.int8)
_COST_TO_OCCUPANCY[1:253] = (1 + (97 * (np.arange(1, 253) - 1)) // 251).astype(np.int8)
_COST_TO_OCCUPANCY[253] = 99
_COST_TO_OCCUPANCY[254] = 100
_COST_TO_OCCUPANCY[255] = -1


def costmap_to_occupancy_values(costmap: Costmap2D) -> np.ndarray:
    return _COST_TO_OCCUPANCY[costmap.data]


def goal_poses(goal: Any) -> list[tuple[float, float, float]]:
    """The map poses a goal message carries (pose, poses, poses.goals or goal), for the run record."""
    found: list[tuple[float, float, float]] = []
    for name in ("pose", "goal", "poses", "dock_pose"):
        value = getattr(goal, name, None)
        if isinstance(value, PoseStamped):
            found.append(pose_to_tuple(value))
        elif isinstance(value, (list, tuple)):
            found.extend(pose_to_tuple(p) for p in value if isinstance(p, PoseStamped))
        elif value is not None and hasattr(value, "goals"):
            found.extend(pose_to_tuple(p) for p in value.goals)
    return [p for p in found if all(math.isfinite(v) for v in p)]


def fill_message(msg: Any, values: Mapping[str, Any], stamp: float = 0.0) -> Any:
    """Set `msg`'s fields from a dict of core values, converting by each field's declared ROS type."""
    types = msg.get_fields_and_field_types()
    for name, value in values.items():
        field_type = types.get(name)
        if field_type is None or value is None:
            continue
        setattr(msg, name, _convert(field_type, value, getattr(msg, name), stamp))
    return msg


def _convert(field_type: str, value: Any, current: Any, stamp: float) -> Any:
    if field_type == "geometry_msgs/PoseStamped":
        return value if isinstance(value, PoseStamped) else pose_stamped(value, stamp)
    if field_type == "builtin_interfaces/Duration":
        return value if isinstance(value, Duration) else duration_msg(float(value))
    if field_type == "nav_msgs/Path":
        return value if isinstance(value, Path) else path_msg(value, stamp)
    if field_type.startswith("sequence<") and "/" in field_type:
        inner = field_type[len("sequence<") : -1].split(",")[0]
        cls = _message_class(inner)
        if inner == "nav2_msgs/MissedWaypoint":  # Jazzy's missed waypoints; the core reports WaypointStatus dicts
            value = [item if isinstance(item, cls) else as_missed_waypoint(item) for item in value]
        return [item if isinstance(item, cls) else fill_message(cls(), item, stamp) for item in value]
    if field_type in ("float", "double"):
        return float(value)
    if field_type.startswith(("int", "uint")):
        return int(value)
    if field_type == "boolean":
        return bool(value)
    if field_type == "string":
        return str(value)
    if isinstance(value, Mapping):
        return fill_message(current, value, stamp)
    return value


def _message_class(type_name: str) -> Any:
    import importlib

    package, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)
