"""The Create 3's own drive goals: drive_distance, rotate_angle, drive_arc, navigate_to_position, wall_follow.

Like the robot (create3_docs "Drive Goals") they close the loop on odometry, not on the true pose; a bump does not
end them (the robot keeps pushing), but a cliff, a wheel stall, a wheel drop, a kidnap or the e-stop abort them.
Each is a small state machine that only proposes (v, w) every physics step, like the dock actions; goals are
validated when created (ValueError with the reason), so a NaN or a negative speed never reaches the wheels.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from tb4.core.geometry import Pose, wrap_angle
from tb4.core.robot_params import DriveParams
from tb4.sim.dock import DockActionState
from tb4.sim.goal_state import FAILED, SUCCEEDED

__all__ = [
    "MotionState",
    "DriveDistance",
    "RotateAngle",
    "DriveArc",
    "NavigateToPosition",
    "WallFollow",
    "MAX_DISTANCE",
    "build_drive_goal",
]

MAX_DISTANCE = 1000.0  # m: farther goals are rejected as garbage
LINEAR_DECEL = 0.5  # m/s^2 planned when slowing down for the goal (below the drive's ramp)
ANGULAR_DECEL = 1.5  # rad/s^2
_DIST_TOL = 0.002  # m
_ANGLE_TOL = 0.003  # rad


class MotionState(DockActionState):
    """Progress of one goal, read by the action server: a dock action's status, reason, cancel and finish (sees_dock
    is set by the simulation for every action), plus the goal's feedback() and result() fields."""

    def __init__(self, kind: str) -> None:
        super().__init__(kind)
        self.fields: dict[str, Any] = {}
        self.final_pose: Pose | None = None
        self.result_extra: dict[str, Any] = {}

    def feedback(self) -> dict[str, Any]:
        return dict(self.fields)

    def result(self) -> dict[str, Any]:
        return {"pose": self.final_pose, **self.result_extra}

    def __repr__(self) -> str:
        return f"MotionState({self.kind!r}, {self.status!r}, {self.reason!r})"


def finite(value: Any, name: str) -> float:
    try:
        f = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} is not a number: {value!r}") from None
    if not math.isfinite(f):
        raise ValueError(f"{name} must be finite, got {f}")
    return f


def positive_speed(value: Any, name: str, cap: float) -> float:
    f = finite(value, name)
    if f <= 0.0:
        raise ValueError(f"{name} must be positive, got {f:g}")
    return min(f, cap)


def turn_angle(value: Any) -> float:
    """A goal's `angle` (rad): finite and at most 50 turns either way."""
    angle = finite(value, "angle")
    if abs(angle) > 100.0 * math.pi:
        raise ValueError(f"angle {angle:g} rad is more than 50 turns")
    return angle


def _slow_for(remaining: float, decel: float, floor: float, cap: float) -> float:
    """Speed that stops within `remaining` at `decel`, at least `floor` (the last millimetres), at most `cap`."""
    return min(cap, max(floor, math.sqrt(2.0 * decel * max(remaining, 0.0))))


class _Motion:
    """Common part: odometry access, the unwrapped heading turned so far, the end of the goal."""

    kind = "motion"

    def __init__(self, odom: Callable[[], Pose], drive: DriveParams) -> None:
        self.state = MotionState(self.kind)
        self.odom = odom
        self.drive = drive
        self.start = odom()
        self._last_yaw = self.start[2]
        self.turned = 0.0

    def _track_turn(self, yaw: float) -> None:
        self.turned += wrap_angle(yaw - self._last_yaw)
        self._last_yaw = yaw

    def _angle_left(self, angle: float) -> float | None:
        """Angle still to turn towards `angle` (feedback updated); None once reached or passed (succeeded)."""
        self._track_turn(self.odom()[2])
        left = angle - self.turned
        self.state.fields = {"remaining_angle_travel": left}
        if abs(left) <= _ANGLE_TOL or left * angle < 0.0:
            self._succeed()
            return None
        return left

    def _succeed(self) -> None:
        self.state.final_pose = self.odom()
        self.state.finish(SUCCEEDED, f"{self.kind} done")

    def abort(self, reason: str) -> None:
        self.state.final_pose = self.odom()
        self.state.finish(FAILED, reason)

    def update(self, pose: Pose, time: float, bumped: bool) -> None:
        if self.state.done and self.state.final_pose is None:
            self.state.final_pose = self.odom()


class DriveDistance(_Motion):
    """Straight line along the start heading; a negative distance drives backwards."""

    kind = "drive_distance"

    def __init__(self, odom: Callable[[], Pose], drive: DriveParams, distance: Any, max_speed: Any) -> None:
        self.distance = finite(distance, "distance")
        if abs(self.distance) > MAX_DISTANCE:
            raise ValueError(f"distance {self.distance:g} m is beyond {MAX_DISTANCE:g} m")
        self.speed = positive_speed(max_speed, "max_translation_speed", drive.max_linear_speed)
        super().__init__(odom, drive)
        self.state.fields = {"remaining_travel_distance": abs(self.distance)}

    def remaining(self) -> float:
        x, y, _ = self.odom()
        c, s = math.cos(self.start[2]), math.sin(self.start[2])
        along = (x - self.start[0]) * c + (y - self.start[1]) * s
        return abs(self.distance) - math.copysign(1.0, self.distance) * along

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        left = self.remaining()
        self.state.fields = {"remaining_travel_distance": max(left, 0.0)}
        if left <= _DIST_TOL:
            self._succeed()
            return (0.0, 0.0)
        return (math.copysign(_slow_for(left, LINEAR_DECEL, 0.01, self.speed), self.distance), 0.0)


class _Turn(_Motion):
    """A goal that ends when the heading has changed by `angle` (set before __init__); `turn` says how to move."""

    angle: float

    def __init__(self, odom: Callable[[], Pose], drive: DriveParams) -> None:
        super().__init__(odom, drive)
        self.state.fields = {"remaining_angle_travel": self.angle}

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        left = self._angle_left(self.angle)
        return (0.0, 0.0) if left is None else self.turn(left)

    def turn(self, left: float) -> tuple[float, float]:
        """(v, w) with `left` rad still to turn (never 0)."""
        raise NotImplementedError


class RotateAngle(_Turn):
    """Turn in place by a relative angle (more than 2 pi turns several times)."""

    kind = "rotate_angle"

    def __init__(self, odom: Callable[[], Pose], drive: DriveParams, angle: Any, max_speed: Any) -> None:
        self.angle = turn_angle(angle)
        self.speed = positive_speed(max_speed, "max_rotation_speed", drive.max_angular_speed)
        super().__init__(odom, drive)

    def turn(self, left: float) -> tuple[float, float]:
        return (0.0, math.copysign(_slow_for(abs(left), ANGULAR_DECEL, 0.05, self.speed), left))


class DriveArc(_Turn):
    """Drive along a circle of `radius` until the heading changed by `angle`, forwards or backwards."""

    kind = "drive_arc"

    def __init__(
        self, odom: Callable[[], Pose], drive: DriveParams, direction: Any, angle: Any, radius: Any, max_speed: Any
    ) -> None:
        if direction not in (1, -1):
            raise ValueError(f"translate_direction must be 1 (forward) or -1 (backward), got {direction!r}")
        self.direction = int(direction)
        self.angle = turn_angle(angle)
        self.radius = finite(radius, "radius")
        if not (0.0 < self.radius <= MAX_DISTANCE):
            raise ValueError(f"radius must be within (0, {MAX_DISTANCE:g}] m, got {self.radius:g}")
        self.speed = positive_speed(max_speed, "max_translation_speed", drive.max_linear_speed)
        self.speed = min(self.speed, drive.max_angular_speed * self.radius)
        super().__init__(odom, drive)

    def turn(self, left: float) -> tuple[float, float]:
        w = _slow_for(abs(left), ANGULAR_DECEL, 0.05, self.speed / self.radius)
        v = w * self.radius
        # the heading turns the way `angle` says whichever way the robot drives
        return (self.direction * v, math.copysign(w, left))


class NavigateToPosition(_Motion):
    """Rotate to face the goal, drive to it, then (optionally) rotate to its heading; all in the odom frame."""

    kind = "navigate_to_position"
    ROTATING_TO_GOAL_POSITION, DRIVING_TO_GOAL_POSITION, ROTATING_TO_GOAL_ORIENTATION = 1, 2, 3

    def __init__(
        self,
        odom: Callable[[], Pose],
        drive: DriveParams,
        goal: Sequence[float],
        achieve_heading: bool,
        max_speed: Any,
        max_rotation: Any,
    ) -> None:
        gx, gy, gyaw = (finite(v, n) for v, n in zip(goal, ("goal x", "goal y", "goal heading"), strict=True))
        self.speed = positive_speed(max_speed, "max_translation_speed", drive.max_linear_speed)
        self.turn = positive_speed(max_rotation, "max_rotation_speed", drive.max_angular_speed)
        super().__init__(odom, drive)
        if math.hypot(gx - self.start[0], gy - self.start[1]) > MAX_DISTANCE:
            raise ValueError(f"goal ({gx:g}, {gy:g}) is more than {MAX_DISTANCE:g} m away: unreachable")
        self.goal = (gx, gy, wrap_angle(gyaw))
        self.achieve_heading = bool(achieve_heading)
        self.phase = self.ROTATING_TO_GOAL_POSITION
        self.state.fields = {"navigate_state": self.phase, "remaining_angle_travel": 0.0}

    def _feedback(self, angle: float = 0.0, distance: float = 0.0) -> None:
        self.state.fields = {
            "navigate_state": self.phase,
            "remaining_angle_travel": angle,
            "remaining_travel_distance": distance,
        }

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        x, y, yaw = self.odom()
        gx, gy, gyaw = self.goal
        dist = math.hypot(gx - x, gy - y)
        if self.phase == self.ROTATING_TO_GOAL_POSITION:
            err = wrap_angle(math.atan2(gy - y, gx - x) - yaw) if dist > 0.01 else 0.0
            self._feedback(angle=err)
            if abs(err) > _ANGLE_TOL:
                return (0.0, math.copysign(_slow_for(abs(err), ANGULAR_DECEL, 0.05, self.turn), err))
            self.phase = self.DRIVING_TO_GOAL_POSITION
        if self.phase == self.DRIVING_TO_GOAL_POSITION:
            c, s = math.cos(yaw), math.sin(yaw)
            ahead = (gx - x) * c + (gy - y) * s
            self._feedback(distance=dist)
            if dist > _DIST_TOL and ahead > 0.0:
                err = wrap_angle(math.atan2(gy - y, gx - x) - yaw) if dist > 0.02 else 0.0
                w = max(-self.turn, min(self.turn, 2.0 * err))
                return (_slow_for(ahead, LINEAR_DECEL, 0.01, self.speed), w)
            self.phase = self.ROTATING_TO_GOAL_ORIENTATION
        err = wrap_angle(gyaw - yaw) if self.achieve_heading else 0.0
        self._feedback(angle=err)
        if abs(err) > _ANGLE_TOL:
            return (0.0, math.copysign(_slow_for(abs(err), ANGULAR_DECEL, 0.05, self.turn), err))
        self._succeed()
        return (0.0, 0.0)


class WallFollow(_Motion):
    """Follow the wall on one side with the IR sensors (and the bumper) until `max_runtime` has passed."""

    kind = "wall_follow"
    TARGET = 0.06  # m kept between the bumper and the wall
    SPEED = 0.2  # m/s along a straight wall

    def __init__(
        self,
        odom: Callable[[], Pose],
        drive: DriveParams,
        side: Any,
        max_runtime: Any,
        start_time: float,
        sense: Callable[[], tuple[float, float, float]],
        bumped: Callable[[], bool],
    ) -> None:
        if side not in (1, -1):
            raise ValueError(f"follow_side must be 1 (FOLLOW_LEFT) or -1 (FOLLOW_RIGHT), got {side!r}")
        self.side = int(side)
        self.runtime = finite(max_runtime, "max_runtime")
        if self.runtime <= 0.0:
            raise ValueError(f"max_runtime must be positive, got {self.runtime:g} s")
        super().__init__(odom, drive)
        self.start_time = start_time
        self.sense = sense  # (front, diagonal, side) beam distances on the followed side, m (inf: nothing)
        self.bumped = bumped
        self.backing_until = -math.inf
        self.engaged = False
        self.elapsed = 0.0
        self.state.fields = {"engaged": False}

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        self.elapsed = time - self.start_time
        self.state.result_extra = {"runtime": self.elapsed}
        if self.elapsed >= self.runtime - 1e-9:
            self.state.fields = {"engaged": self.engaged}
            self._succeed()
            return (0.0, 0.0)
        side = self.side
        if self.bumped():
            self.backing_until = time + 0.3
        if time < self.backing_until:  # back off the contact while turning away from the wall
            return (-0.05, -side * 1.2)
        front, diagonal, lateral = self.sense()
        self.engaged = min(diagonal, lateral) < 3.0 * self.TARGET or front < 2.0 * self.TARGET
        self.state.fields = {"engaged": self.engaged}
        if front < 1.5 * self.TARGET:  # wall ahead: turn away in place
            return (0.0, -side * 1.0)
        gap = min(lateral, diagonal * 0.7)
        if not math.isfinite(gap):
            return (self.SPEED * 0.6, side * 0.8)  # lost the wall: arc towards the side
        err = max(-0.1, min(0.1, gap - self.TARGET))
        return (self.SPEED, max(-1.2, min(1.2, side * 12.0 * err)))


#: the drive goals by action name, each built from (odom, drive params, the goal's fields as plain values)
_PLAIN_GOALS: dict[str, Callable[..., _Motion]] = {
    "drive_distance": DriveDistance,
    "rotate_angle": RotateAngle,
    "drive_arc": DriveArc,
    "navigate_to_position": NavigateToPosition,
}


def build_drive_goal(
    action: str,
    odom: Callable[[], Pose],
    drive: DriveParams,
    fields: Sequence[Any],
    start_time: float = 0.0,
    sense: Callable[[], tuple[float, float, float]] | None = None,
    bumped: Callable[[], bool] | None = None,
) -> _Motion:
    """A drive goal from its action's name and its goal's fields as plain values (a replayable input).

    Args:
        action: drive_distance, rotate_angle, drive_arc, navigate_to_position or wall_follow.
        odom: the odometry pose the goal closes its loop on.
        drive: the drive's limits.
        fields: the goal's fields, in the order of the class's arguments after `drive` (wall_follow:
            follow_side and max_runtime).
        start_time: wall_follow's start (sim s).
        sense: wall_follow's IR ranges on its side (none: nothing seen).
        bumped: wall_follow's bumper (none: never pressed).

    Returns:
        The goal, ready to start.

    Raises:
        ValueError: an unknown action, or a malformed goal (with the reason).
    """
    if action == "wall_follow":
        side, runtime = fields
        far = (math.inf, math.inf, math.inf)
        return WallFollow(odom, drive, side, runtime, start_time, sense or (lambda: far), bumped or (lambda: False))
    build = _PLAIN_GOALS.get(action)
    if build is None:
        raise ValueError(f"unknown drive goal {action!r}: one of {', '.join([*_PLAIN_GOALS, 'wall_follow'])}")
    return build(odom, drive, *fields)
