"""Goal fields built from the user's arguments, checked before anything is sent: durations, flags, waypoint loops,
GPS poses and route endpoints (an id or a pose)."""

from __future__ import annotations

import math
from typing import Any

from builtin_interfaces.msg import Duration
from geographic_msgs.msg import GeoPose
from geometry_msgs.msg import PoseStamped

from tb4.core.units import to_sec_nanosec
from tb4.navigator._validate import check_number, check_pose_stamped

__all__ = ["check_flag", "check_geo_poses", "check_loops", "fill_route_goal", "is_route_id", "seconds_msg"]

_UINT16_MAX = 0xFFFF


def check_loops(number_of_loops: Any, goal_index: Any, count: int) -> None:
    for value, what in ((number_of_loops, "number_of_loops"), (goal_index, "goal_index")):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0 or value > 0xFFFFFFFF:
            raise ValueError(f"{what} must be a non-negative int (uint32), got {value!r}")
    if goal_index >= count:
        raise ValueError(f"goal_index {goal_index} is out of range for {count} waypoints")


def check_geo_poses(gps_poses: Any, what: str = "gps_poses") -> list[GeoPose]:
    """A non-empty list of geographic_msgs/GeoPose with a valid WGS 84 position and a usable orientation."""
    if isinstance(gps_poses, (str, bytes, GeoPose)) or not isinstance(gps_poses, (list, tuple)):
        raise TypeError(f"{what} must be a list of geographic_msgs/GeoPose, got {type(gps_poses).__name__}")
    if not gps_poses:
        raise ValueError(f"{what} is empty: give at least one GeoPose")
    for i, pose in enumerate(gps_poses):
        name = f"{what}[{i}]"
        if not isinstance(pose, GeoPose):
            raise TypeError(f"{name} must be a geographic_msgs/GeoPose, got {type(pose).__name__}")
        lat, lon, alt = pose.position.latitude, pose.position.longitude, pose.position.altitude
        if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
            raise ValueError(f"{name}: latitude must be within [-90, 90] degrees, got {lat!r}")
        if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
            raise ValueError(f"{name}: longitude must be within [-180, 180] degrees, got {lon!r}")
        if math.isinf(alt):  # NaN is geographic_msgs' "no altitude"
            raise ValueError(f"{name}: altitude must be finite or NaN (unknown), got {alt!r}")
        q = pose.orientation
        values = (q.x, q.y, q.z, q.w)
        if not all(math.isfinite(v) for v in values) or sum(v * v for v in values) < 1e-9:
            raise ValueError(f"{name}: orientation must be a finite, non-zero quaternion, got {values!r}")
    return list(gps_poses)


def seconds_msg(value: Any, what: str) -> Duration:
    """A builtin_interfaces/Duration of `value` positive, finite seconds."""
    seconds = check_number(value, what, positive=True)
    if seconds >= 2**31:
        raise ValueError(f"{what} is too large for a ROS Duration: {value!r}")
    sec, nanosec = to_sec_nanosec(seconds)
    return Duration(sec=sec, nanosec=nanosec)


def check_flag(value: Any, what: str) -> bool:
    if not isinstance(value, (bool, int)):
        raise TypeError(f"{what} must be True or False, got {type(value).__name__}")
    return bool(value)


def is_route_id(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def fill_route_goal(goal: Any, start: Any, target: Any, use_start: bool) -> bool:
    """Fill a ComputeRoute/ComputeAndTrackRoute goal; False if start and goal are not both ids or both poses."""
    goal.use_start = bool(use_start)
    if is_route_id(start) and is_route_id(target):
        for value, what in ((start, "start"), (target, "goal")):
            if not 0 <= value <= _UINT16_MAX:
                raise ValueError(f"{what} node id must be within 0..{_UINT16_MAX} (uint16), got {value}")
        goal.start_id, goal.goal_id, goal.use_poses = start, target, False
        return True
    if isinstance(start, PoseStamped) and isinstance(target, PoseStamped):
        check_pose_stamped(target, "goal")
        if use_start:
            check_pose_stamped(start, "start")
        goal.start, goal.goal, goal.use_poses = start, target, True
        return True
    return False
