"""Planar geometry in one place: the (x, y, yaw) pose, angle wrapping, yaw <-> quaternion and pose composition.

Quaternions are plain (x, y, z, w) tuples so the simulator, the navigation core and the tools share the maths;
tb4.ros.convert wraps them into geometry_msgs. Yaw is counter-clockwise from +x, in radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TypeVar, overload

import numpy as np

__all__ = [
    "Pose",
    "Pose2D",
    "Quaternion",
    "wrap_angle",
    "rewrap",
    "arc_pose",
    "yaw_to_quaternion",
    "quaternion_to_yaw",
    "euler_to_quaternion",
    "compose",
    "inverse",
    "same_pose",
    "SAME_POSITION",
    "SAME_HEADING",
]

#: A map or odom pose: (x, y, yaw) in metres and radians.
Pose = tuple[float, float, float]
#: A unit quaternion as (x, y, z, w).
Quaternion = tuple[float, float, float, float]

#: How far a localizer's estimate may be from a pose it was given and still report that pose (its own estimate of a
#: robot at rest, with the map's resolution and a quaternion's rounding): metres, radians.
SAME_POSITION = 0.15
SAME_HEADING = 0.1

_Angles = TypeVar("_Angles", bound=np.ndarray)


@dataclass(frozen=True)
class Pose2D:
    """A planar pose in metres and radians (yaw counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float


@overload
def wrap_angle(a: float) -> float: ...
@overload
def wrap_angle(a: _Angles) -> _Angles: ...
def wrap_angle(a: float | np.ndarray) -> float | np.ndarray:
    """Angle(s) in [-pi, pi); works element-wise on arrays (the particle filter wraps every particle at once)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def rewrap(a: float, times: int) -> float:
    """`a` after `times` rounds of wrap_angle(a + 0.0): what that many steps without turning leave of a heading
    integrated step by step, to the last bit (it stops at the first round that changes nothing)."""
    for _ in range(times):
        wrapped = wrap_angle(a + 0.0)
        if wrapped == a:
            break
        a = wrapped
    return a


def arc_pose(x: float, y: float, yaw: float, v: float, w: float, t: float) -> tuple[float, float, float]:
    """Pose after driving t seconds at constant (v, w): the exact unicycle arc (a straight line when w == 0);
    the simulator's motion and the controller's collision look-ahead both follow it."""
    if abs(w) < 1e-12:
        return (x + v * t * math.cos(yaw), y + v * t * math.sin(yaw), yaw)
    yaw2 = yaw + w * t
    r = v / w
    return (x + r * (math.sin(yaw2) - math.sin(yaw)), y - r * (math.cos(yaw2) - math.cos(yaw)), wrap_angle(yaw2))


def yaw_to_quaternion(yaw: float) -> Quaternion:
    """The rotation by `yaw` about +z."""
    half = 0.5 * float(yaw)
    return (0.0, 0.0, math.sin(half), math.cos(half))


def quaternion_to_yaw(x: float, y: float, z: float, w: float) -> float:
    """The heading (rotation about +z) of a quaternion; roll and pitch are ignored."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def euler_to_quaternion(roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Quaternion:
    """The quaternion of roll, pitch, yaw (radians, applied as Z-Y-X: yaw, then pitch, then roll)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    )


def compose(a: Pose, b: Pose) -> Pose:
    """a ∘ b: pose b (expressed in frame a) expressed in a's parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap_angle(a[2] + b[2]))


def inverse(a: Pose) -> Pose:
    """The pose that composes with `a` to the identity: compose(a, inverse(a)) == (0, 0, 0)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), wrap_angle(-a[2]))


def same_pose(a: Pose, b: Pose, position: float = SAME_POSITION, heading: float = SAME_HEADING) -> bool:
    """True when `a` and `b` are within `position` metres and `heading` radians of each other.

    Args:
        a, b: (x, y, yaw) poses in one frame.
        position: the largest distance, metres.
        heading: the largest difference of yaw (wrapped), radians.

    Returns:
        Whether the two are the same pose within those bounds.
    """
    return math.hypot(a[0] - b[0], a[1] - b[1]) < position and abs(wrap_angle(a[2] - b[2])) < heading
