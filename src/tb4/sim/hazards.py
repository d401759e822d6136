"""Create 3 hazard sensing: which bumper zone touches, cliff and wheel-drop sensors, and the backup limit.

Hazard types and sensor frame names follow irobot_create_msgs/HazardDetection and the Create 3's tf tree, so the
ROS layer only copies them. The backup limit follows create3_docs (safety): the robot may reverse only as far as
it has driven forward ("explored"), up to `backup_limit`; it reports BACKUP_LIMIT from `backup_warning` before the
end, then refuses to reverse until it drives forward again. A kidnap empties the allowance at once.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from tb4.core.robot_params import Create3Params

__all__ = [
    "BACKUP_LIMIT",
    "BUMP",
    "CLIFF",
    "STALL",
    "WHEEL_DROP",
    "Hazard",
    "bump_frame",
    "contact_angle",
    "CLIFF_FRAMES",
    "cliff_points",
    "wheel_points",
    "CliffMap",
    "BackupLimit",
]

# irobot_create_msgs/HazardDetection types
BACKUP_LIMIT, BUMP, CLIFF, STALL, WHEEL_DROP = 0, 1, 2, 3, 4

CLIFF_FRAMES = ("cliff_side_left", "cliff_front_left", "cliff_front_right", "cliff_side_right")
WHEEL_FRAMES = ("wheel_drop_left", "wheel_drop_right")
# bumper zones by contact angle (deg, counter-clockwise from the heading), left to right
_BUMP_ZONES = (
    (54.0, "bump_left"),
    (18.0, "bump_front_left"),
    (-18.0, "bump_front_center"),
    (-54.0, "bump_front_right"),
)


@dataclass(frozen=True)
class Hazard:
    """One currently detected hazard: its HazardDetection type and the frame of the sensor that saw it."""

    type: int
    frame: str


def bump_frame(angle: float) -> str:
    """Bumper zone for a contact at `angle` (rad, robot frame). Contacts behind the axle press the side zones."""
    deg = math.degrees(math.atan2(math.sin(angle), math.cos(angle)))
    for lower, frame in _BUMP_ZONES:
        if deg >= lower:
            return frame
    return "bump_right"


def contact_angle(x: float, y: float, yaw: float, clearance: Callable[[float, float], float], radius: float) -> float:
    """Direction (rad, robot frame) of the nearest surface around the footprint: where the bumper is pressed.
    A coarse pass every 15 degrees, then a fine one every 2.5 degrees around the best (30 probes in all)."""
    probe = radius + 0.01

    def best_of(angles: Sequence[float]) -> float:
        best, best_angle = math.inf, 0.0
        for a in angles:
            c = clearance(x + probe * math.cos(yaw + a), y + probe * math.sin(yaw + a))
            if c < best - 1e-12 or (abs(c - best) <= 1e-12 and abs(a) < abs(best_angle)):
                best, best_angle = c, a
        return best_angle

    coarse = best_of([math.radians(d) for d in range(-180, 180, 15)])
    fine = best_of([coarse + math.radians(2.5 * k) for k in range(-3, 4)])
    return math.atan2(math.sin(fine), math.cos(fine))


def cliff_points(x: float, y: float, yaw: float, p: Create3Params) -> list[tuple[str, float, float]]:
    """(frame, x, y) of each cliff sensor at the robot pose."""
    out = []
    for frame, deg in zip(CLIFF_FRAMES, p.cliff_angles, strict=False):
        a = yaw + math.radians(deg)
        out.append((frame, x + p.cliff_radius * math.cos(a), y + p.cliff_radius * math.sin(a)))
    return out


def wheel_points(x: float, y: float, yaw: float, p: Create3Params) -> list[tuple[str, float, float]]:
    """(frame, x, y) of the left and right wheel contact points."""
    h = 0.5 * p.wheel_base
    s, c = math.sin(yaw), math.cos(yaw)
    return [(WHEEL_FRAMES[0], x - s * h, y + c * h), (WHEEL_FRAMES[1], x + s * h, y - c * h)]


class CliffMap:
    """Floor drops marked in the world file (`cliffs:` boxes and circles): stairs, a loading-dock edge.

    Plain-Python geometry (the world's Obstacle.contains works on arrays and costs microseconds per call): this
    is asked for six points every physics step."""

    def __init__(self, regions: Sequence[Any] = ()) -> None:
        self.regions = tuple(regions)
        self._shapes: list[tuple[float, float, float, float, float, float, float]] = []
        for r in self.regions:
            cx, cy = (float(v) for v in r.position_at(0.0))
            if r.shape == "circle":
                self._shapes.append((cx, cy, r.radius, 1.0, 0.0, -1.0, -1.0))
            else:
                half_l, half_w = 0.5 * r.size[0], 0.5 * r.size[1]
                self._shapes.append(
                    (cx, cy, math.hypot(half_l, half_w), math.cos(r.yaw), math.sin(r.yaw), half_l, half_w)
                )

    def __bool__(self) -> bool:
        return bool(self._shapes)

    def gap(self, x: float, y: float) -> float:
        """A lower bound of the distance from (x, y) to every region (0 when close to or inside one)."""
        return max(
            0.0, min((math.hypot(x - cx, y - cy) - extent for cx, cy, extent, *_ in self._shapes), default=math.inf)
        )

    def over(self, x: float, y: float) -> bool:
        for cx, cy, extent, c, s, half_l, half_w in self._shapes:
            dx, dy = x - cx, y - cy
            if half_l < 0.0:
                if dx * dx + dy * dy <= extent * extent:
                    return True
            elif abs(dx * c + dy * s) <= half_l and abs(-dx * s + dy * c) <= half_w:
                return True
        return False


class BackupLimit:
    """How far the robot may still reverse: grows with forward travel (up to the limit), shrinks when reversing."""

    def __init__(self, p: Create3Params) -> None:
        self.limit = p.backup_limit
        self.warning = p.backup_warning
        self.allowance = p.backup_limit  # the robot starts on its dock or where it was placed: explored
        self.stopped = False  # hit the limit: backward motion refused until the robot drives forward

    def travel(self, distance: float) -> None:
        """Account a signed distance driven along the heading."""
        if distance > 0.0:
            self.allowance = min(self.limit, self.allowance + distance)
            if self.allowance >= self.warning:
                self.stopped = False
        elif distance < 0.0:
            self.allowance = max(0.0, self.allowance + distance)
            if self.allowance <= 1e-9:
                self.stopped = True

    def allows(self, v: float) -> bool:
        return v >= 0.0 or (not self.stopped and self.allowance > 1e-9)

    @property
    def reported(self) -> bool:
        """BACKUP_LIMIT is in hazard_detection: about to trigger, or triggered."""
        return self.stopped or self.allowance < self.warning

    def kidnapped(self) -> None:
        self.allowance = 0.0
        self.stopped = True
