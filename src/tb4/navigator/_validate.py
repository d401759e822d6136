"""Argument checks run before anything is sent: a NaN goal or a wrong type fails here, with the argument named."""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

from geometry_msgs.msg import Pose, PoseStamped
from nav_msgs.msg import Goals, Path

__all__ = ["check_number", "check_pose_stamped", "check_poses", "check_path", "check_name", "goals_to_list"]


def check_number(value: Any, what: str, *, positive: bool = False, non_negative: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):  # numbers.Real admits NumPy scalars
        raise TypeError(f"{what} must be a number, got {type(value).__name__} ({value!r})")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError(f"{what} must be finite, got {value!r}")
    if positive and number <= 0:
        raise ValueError(f"{what} must be positive, got {value!r}")
    if non_negative and number < 0:
        raise ValueError(f"{what} must not be negative, got {value!r}")
    return number


def check_name(value: Any, what: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{what} must be a string, got {type(value).__name__} ({value!r})")
    return value


def _check_pose(pose: Pose, what: str) -> None:
    p, q = pose.position, pose.orientation
    for axis, v in (("x", p.x), ("y", p.y), ("z", p.z)):
        if not math.isfinite(v):
            raise ValueError(f"{what}: position.{axis} must be finite, got {v!r}")
    values = (q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{what}: orientation must be finite, got {values!r}")
    if sum(v * v for v in values) < 1e-9:
        raise ValueError(f"{what}: orientation is a zero quaternion (set w=1.0 for 'no rotation')")


def check_pose_stamped(pose: Any, what: str = "pose") -> PoseStamped:
    if not isinstance(pose, PoseStamped):
        hint = " (use navigator.getPoseStamped([x, y], direction))" if isinstance(pose, (list, tuple)) else ""
        raise TypeError(f"{what} must be a geometry_msgs/PoseStamped, got {type(pose).__name__}{hint}")
    _check_pose(pose.pose, what)
    return pose


def goals_to_list(poses: Any, what: str = "poses") -> list[Any]:
    """Accept a list/tuple of PoseStamped (Jazzy style) or a nav_msgs/Goals message (Kilted style)."""
    if isinstance(poses, Goals):
        return list(poses.goals)
    if isinstance(poses, (str, bytes)) or not isinstance(poses, Sequence):
        raise TypeError(f"{what} must be a list of PoseStamped or a nav_msgs/Goals, got {type(poses).__name__}")
    return list(poses)


def check_poses(poses: Any, what: str = "poses") -> list[PoseStamped]:
    items = goals_to_list(poses, what)
    if not items:
        raise ValueError(f"{what} is empty: give at least one PoseStamped")
    return [check_pose_stamped(p, f"{what}[{i}]") for i, p in enumerate(items)]


def check_path(path: Any, what: str = "path") -> Path:
    if not isinstance(path, Path):
        raise TypeError(f"{what} must be a nav_msgs/Path, got {type(path).__name__}")
    if not path.poses:
        raise ValueError(f"{what} has no poses")
    for i, p in enumerate(path.poses):
        _check_pose(p.pose, f"{what}.poses[{i}]")
    return path
