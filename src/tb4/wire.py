"""The Nav2 wire format the installed nav2_msgs speaks (Kilted or Jazzy), and the few field differences to bridge.

A TurtleBot 4 on ROS 2 Jazzy and Nav2 Kilted disagree on the wire in a handful of places: NavigateThroughPoses and
ComputePathThroughPoses carry their poses as ``nav_msgs/Goals`` in Kilted and as ``PoseStamped[]`` in Jazzy; Kilted
adds ``waypoint_statuses``, ``disable_collision_checks`` and IsPathValid's ``max_cost`` /
``consider_unknown_as_obstacle``; FollowWaypoints reports missed waypoints as ``WaypointStatus`` (Kilted) or
``MissedWaypoint`` (Jazzy). The install builds one of the two (``TB4_ROS_DISTRO=kilted|jazzy make install``). The
navigator, the simulator and the viewer ask this module rather than a flag, so the same code speaks whichever format
is installed, choosing by the types themselves.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from typing import Any

__all__ = [
    "WIRE_FORMATS",
    "wire_format",
    "has_field",
    "set_poses",
    "get_poses",
    "set_supported",
    "get_optional",
    "missed_waypoint",
    "missed_waypoint_fields",
    "as_missed_waypoint",
    "result_code",
]

#: The wire formats an install can build, by ROS 2 distribution name.
WIRE_FORMATS = ("kilted", "jazzy")


@functools.cache
def wire_format() -> str:
    """'kilted' or 'jazzy': read off the installed NavigateThroughPoses goal, the clearest of the differences."""
    from nav2_msgs.action import NavigateThroughPoses

    poses_type = NavigateThroughPoses.Goal.get_fields_and_field_types()["poses"]
    if poses_type == "nav_msgs/Goals":
        return "kilted"
    if poses_type == "sequence<geometry_msgs/PoseStamped>":
        return "jazzy"
    raise RuntimeError(f"unknown nav2_msgs build: NavigateThroughPoses.Goal.poses is {poses_type!r}")


def has_field(msg: Any, name: str) -> bool:
    """Whether a message (class or instance) has this field in the installed wire format."""
    return name in msg.get_fields_and_field_types()


def set_poses(msg: Any, field: str, poses: Sequence[Any], header: Any = None) -> None:
    """Fill a pose-list field (NavigateThroughPoses ``poses``, ComputePathThroughPoses ``goals``) in either format.

    Kilted's ``nav_msgs/Goals`` has a header of its own: `header`, or else the first pose's."""
    if msg.get_fields_and_field_types()[field] == "nav_msgs/Goals":
        from nav_msgs.msg import Goals

        goals = Goals(goals=list(poses))
        if header is not None:
            goals.header = header
        elif poses:
            goals.header = poses[0].header
        setattr(msg, field, goals)
    else:
        setattr(msg, field, list(poses))


def get_poses(msg: Any, field: str) -> list[Any]:
    """The PoseStamped list of a pose-list field, whichever format carried it."""
    value = getattr(msg, field)
    return list(value.goals) if hasattr(value, "goals") else list(value)


def set_supported(msg: Any, **fields: Any) -> list[str]:
    """Set each field the installed format has; return the names it lacks (the caller decides whether that matters)."""
    known = msg.get_fields_and_field_types()
    missing = []
    for name, value in fields.items():
        if name in known:
            setattr(msg, name, value)
        else:
            missing.append(name)
    return missing


def get_optional(msg: Any, name: str, default: Any) -> Any:
    """A field that only one format has, or `default` (upstream's default for it) where the other format lacks it."""
    return getattr(msg, name) if has_field(msg, name) else default


def missed_waypoint(index: int, pose: Any, error_code: int, error_msg: str = "") -> Any:
    """One entry of FollowWaypoints' ``missed_waypoints``: a failed WaypointStatus (Kilted) or a MissedWaypoint."""
    from nav2_msgs.action import FollowWaypoints

    entry_type = FollowWaypoints.Result.get_fields_and_field_types()["missed_waypoints"]
    if "WaypointStatus" in entry_type:
        from nav2_msgs.msg import WaypointStatus

        return WaypointStatus(
            waypoint_status=WaypointStatus.FAILED,
            waypoint_index=int(index),
            waypoint_pose=pose,
            error_code=int(error_code),
            error_msg=str(error_msg),
        )
    from nav2_msgs.msg import MissedWaypoint  # type: ignore[attr-defined]  # Jazzy builds only

    return MissedWaypoint(index=int(index), goal=pose, error_code=int(error_code))


def missed_waypoint_fields(entry: Any) -> tuple[int, Any, int, str]:
    """(index, pose, error_code, error_msg) of a missed-waypoint entry in either format (Jazzy has no message)."""
    if hasattr(entry, "waypoint_index"):
        return int(entry.waypoint_index), entry.waypoint_pose, int(entry.error_code), str(entry.error_msg)
    return int(entry.index), entry.goal, int(entry.error_code), ""


def as_missed_waypoint(status: Mapping[str, Any]) -> Mapping[str, Any]:
    """A WaypointStatus as a dict (the core's form) in the fields of Jazzy's MissedWaypoint (index, goal, code)."""
    return {"index": status["waypoint_index"], "goal": status["waypoint_pose"], "error_code": status["error_code"]}


#: Kilted's values of the result codes that Jazzy's nav2_msgs does not declare. On the wire a code is a number
#: either way; a Jazzy client shows the number where a Kilted one shows the name.
_KILTED_ONLY_CODES: dict[tuple[str, str], int] = {
    ("NavigateToPose", "UNKNOWN"): 9000,
    ("NavigateToPose", "FAILED_TO_LOAD_BEHAVIOR_TREE"): 9001,
    ("NavigateToPose", "TF_ERROR"): 9002,
    ("NavigateToPose", "TIMEOUT"): 9003,
    ("NavigateThroughPoses", "UNKNOWN"): 9100,
    ("NavigateThroughPoses", "FAILED_TO_LOAD_BEHAVIOR_TREE"): 9101,
    ("NavigateThroughPoses", "TF_ERROR"): 9102,
    ("NavigateThroughPoses", "TIMEOUT"): 9103,
    ("FollowWaypoints", "NO_VALID_WAYPOINTS"): 602,
    ("FollowWaypoints", "STOP_ON_MISSED_WAYPOINT"): 603,
    ("FollowGPSWaypoints", "NO_WAYPOINTS_GIVEN"): 602,
    ("FollowGPSWaypoints", "STOP_ON_MISSED_WAYPOINT"): 603,
    ("DockRobot", "TIMEOUT"): 907,
    ("UndockRobot", "TIMEOUT"): 907,
    ("Wait", "NONE"): 0,
    ("Wait", "UNKNOWN"): 740,
    ("Wait", "TIMEOUT"): 741,
}


def result_code(action: Any, name: str) -> int:
    """An action's result code by name: the installed constant, or Kilted's number where Jazzy has none."""
    value = getattr(action.Result, name, None)
    if value is not None:
        return int(value)
    return _KILTED_ONLY_CODES[(action.__name__, name)]
