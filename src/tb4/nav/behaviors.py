"""Nav2 behaviour-server actions as tasks: spin, backup, drive_on_heading, wait, assisted_teleop.

They work in the local costmap's frame (odom before localization), so they run without an initial pose, as in
Nav2. Collision checks use the round footprint against LETHAL cells of the local costmap, simulating
`simulate_ahead_time` ahead; results carry the action's error codes (interfaces.md).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tb4.core.geometry import Pose, wrap_angle
from tb4.nav.controller import arc_poses, footprint_in_collision
from tb4.nav.tasks import NavContext, Task

__all__ = ["Spin", "BackUp", "DriveOnHeading", "Wait", "AssistedTeleop", "TELEOP_TIMEOUT"]

TELEOP_TIMEOUT = 0.5  # s: a teleop command older than this counts as "stop" (like the base's cmd_vel timeout)


class _TimedBehavior(Task):
    """Time allowance (<= 0 means none), total_elapsed_time and the per-action error codes."""

    TIMEOUT = 0
    COLLISION_AHEAD = 0

    def __init__(self, time_allowance: float = 10.0, disable_collision_checks: bool = False) -> None:
        super().__init__()
        self.time_allowance = float(time_allowance)
        self.disable_collision_checks = bool(disable_collision_checks)
        self._started = False

    def _timed_out(self, now: float) -> bool:
        return self.time_allowance > 0.0 and self.elapsed(now) > self.time_allowance

    def _step(self, ctx: NavContext, now: float) -> None:
        if not self._started:
            self._started = True
            problem = self._check_input()
            if problem:
                self._fail(getattr(self, "INVALID_INPUT", self.UNKNOWN), problem, now)
                return
            self._begin(ctx, now)
            if self.done:
                return
        if self._timed_out(now):
            self._fail(
                self.TIMEOUT, f"exceeded time allowance {self.time_allowance:.1f} s before {self.name} completed", now
            )
            return
        self._run(ctx, now)

    def _check_input(self) -> str:
        return ""

    def _begin(self, ctx: NavContext, now: float) -> None:
        pass

    def _run(self, ctx: NavContext, now: float) -> None:
        raise NotImplementedError

    def _footprint_radius(self, ctx: NavContext) -> float:
        return float(ctx.params.local_costmap["robot_radius"])

    def result(self) -> dict[str, Any]:
        return {"total_elapsed_time": self.elapsed(), "error_code": self.error_code, "error_msg": self.error_msg}


class Spin(_TimedBehavior):
    """Turn in place by `target_yaw` radians (sign = direction), decelerating to stop on target."""

    name = "spin"
    UNKNOWN, TIMEOUT, TF_ERROR, COLLISION_AHEAD = 700, 701, 702, 703

    def __init__(self, target_yaw: float, time_allowance: float = 10.0, disable_collision_checks: bool = False):
        super().__init__(time_allowance, disable_collision_checks)
        self.target_yaw = float(target_yaw)
        self.traveled = 0.0
        self._prev_yaw: float | None = None

    def _check_input(self) -> str:
        return "" if math.isfinite(self.target_yaw) else f"target_yaw must be finite, got {self.target_yaw}"

    def _begin(self, ctx: NavContext, now: float) -> None:
        self._prev_yaw = ctx.local_pose()[2]

    def _run(self, ctx: NavContext, now: float) -> None:
        pose = ctx.local_pose()
        assert self._prev_yaw is not None
        sign = 1.0 if self.target_yaw >= 0.0 else -1.0
        self.traveled += sign * wrap_angle(pose[2] - self._prev_yaw)
        self._prev_yaw = pose[2]
        remaining = abs(self.target_yaw) - self.traveled
        if remaining <= 1e-3:
            ctx.stop()
            self._succeed(now)
            return
        b = ctx.params.behavior
        costmap = ctx.local_costmap
        radius = self._footprint_radius(ctx)
        if (
            not self.disable_collision_checks
            and costmap is not None
            and footprint_in_collision(costmap, pose[0], pose[1], radius)[0]
        ):
            self._fail(self.COLLISION_AHEAD, "collision ahead: an obstacle is inside the footprint, cannot spin", now)
            return
        w = min(float(b["max_rotational_vel"]), math.sqrt(2.0 * float(b["rotational_acc_lim"]) * remaining))
        w = max(w, float(b["min_rotational_vel"]))
        ctx.send_velocity(0.0, sign * w)

    def feedback(self) -> dict[str, Any]:
        return {"angular_distance_traveled": float(abs(self.traveled))}


class DriveOnHeading(_TimedBehavior):
    """Drive straight `distance` metres at `speed` (both signed; signs must agree) along the current heading."""

    name = "drive_on_heading"
    UNKNOWN, TIMEOUT, TF_ERROR, COLLISION_AHEAD, INVALID_INPUT = 720, 721, 722, 723, 724

    def __init__(
        self,
        distance: float,
        speed: float,
        time_allowance: float = 10.0,
        disable_collision_checks: bool = False,
        target_y: float = 0.0,
        target_z: float = 0.0,
    ) -> None:
        super().__init__(time_allowance, disable_collision_checks)
        self.distance, self.speed = self._signed(float(distance), float(speed))
        self.target_y = float(target_y)
        self.target_z = float(target_z)
        self.traveled = 0.0
        self._start_pose: Pose | None = None

    @staticmethod
    def _signed(distance: float, speed: float) -> tuple[float, float]:
        """The goal's distance and speed as driven: as given (BackUp reverses them)."""
        return distance, speed

    def _check_input(self) -> str:
        if not (math.isfinite(self.distance) and math.isfinite(self.speed)):
            return "distance and speed must be finite"
        if self.target_y != 0.0 or self.target_z != 0.0:
            return f"{self.name} in y and z is not supported (target y={self.target_y}, z={self.target_z})"
        if self.speed == 0.0:
            return "speed must not be zero"
        if self.distance * self.speed < 0.0:
            return f"speed ({self.speed}) and distance ({self.distance}) signs do not match"
        return ""

    def _begin(self, ctx: NavContext, now: float) -> None:
        self._start_pose = ctx.local_pose()
        if self.distance == 0.0:
            self._succeed(now)

    def _run(self, ctx: NavContext, now: float) -> None:
        pose = ctx.local_pose()
        assert self._start_pose is not None
        self.traveled = math.hypot(pose[0] - self._start_pose[0], pose[1] - self._start_pose[1])
        remaining = abs(self.distance) - self.traveled
        if remaining <= 1e-3:
            ctx.stop()
            self._succeed(now)
            return
        sign = 1.0 if self.distance > 0.0 else -1.0
        accel = ctx.params.max_linear_accel
        speed = min(abs(self.speed), ctx.params.max_linear_vel, max(0.02, math.sqrt(2.0 * accel * remaining)))
        costmap = ctx.local_costmap
        if not self.disable_collision_checks and costmap is not None:
            sim_time = float(ctx.params.behavior["simulate_ahead_time"])
            ahead = min(abs(self.speed) * sim_time, remaining)
            n = max(2, int(math.ceil(ahead / (0.5 * float(costmap.resolution)))))
            s = np.linspace(0.0, ahead, n) * sign
            heading = self._start_pose[2]
            xs = pose[0] + s * math.cos(heading)
            ys = pose[1] + s * math.sin(heading)
            motion = heading if sign > 0 else heading + math.pi
            if np.any(footprint_in_collision(costmap, xs, ys, self._footprint_radius(ctx), motion)):
                self._fail(self.COLLISION_AHEAD, f"collision ahead: obstacle within {ahead:.2f} m, stopping", now)
                return
        ctx.send_velocity(sign * speed, 0.0)

    def feedback(self) -> dict[str, Any]:
        return {"distance_traveled": float(self.traveled)}


class BackUp(DriveOnHeading):
    """Reverse `distance` metres at `speed` (Nav2 uses the magnitudes and always drives backwards)."""

    name = "backup"
    UNKNOWN, TIMEOUT, TF_ERROR, INVALID_INPUT, COLLISION_AHEAD = 710, 711, 712, 713, 714

    @staticmethod
    def _signed(distance: float, speed: float) -> tuple[float, float]:
        return -abs(distance), -abs(speed)


class Wait(_TimedBehavior):
    """Do nothing for `duration` seconds (sends no velocity: the base stops on its own command timeout)."""

    name = "wait"
    UNKNOWN, TIMEOUT = 740, 741
    drives = False  # a robot that cannot drive can still wait

    def __init__(self, duration: float) -> None:
        super().__init__(time_allowance=0.0)
        self.duration = float(duration)

    def _check_input(self) -> str:
        return "" if math.isfinite(self.duration) else f"wait time must be finite, got {self.duration}"

    def _run(self, ctx: NavContext, now: float) -> None:
        ctx.stop()
        if self.elapsed(now) >= self.duration - 1e-9:
            self._succeed(now)

    def feedback(self) -> dict[str, Any]:
        return {"time_left": max(0.0, self.duration - self.elapsed())}


class AssistedTeleop(_TimedBehavior):
    """Pass the user's teleop command through, scaled down so the robot never drives into an obstacle.

    `set_teleop_velocity` is fed from `cmd_vel_teleop`; `preempt` (the `preempt_teleop` topic) ends it with
    success; reaching `time_allowance` ends it with TIMEOUT, as in Nav2.
    """

    name = "assisted_teleop"
    UNKNOWN, TIMEOUT, TF_ERROR = 730, 731, 732

    def __init__(self, time_allowance: float = 30.0) -> None:
        super().__init__(time_allowance)
        self._teleop = (0.0, 0.0)
        self._teleop_time = -math.inf
        self._preempted = False
        self.last_command = (0.0, 0.0)

    def set_teleop_velocity(self, v: float, w: float, now: float) -> None:
        if math.isfinite(v) and math.isfinite(w):
            self._teleop = (float(v), float(w))
            self._teleop_time = float(now)

    def preempt(self) -> None:
        self._preempted = True

    def _run(self, ctx: NavContext, now: float) -> None:
        if self._preempted:
            ctx.stop()
            self._succeed(now)
            return
        v, w = self._teleop if now - self._teleop_time <= TELEOP_TIMEOUT else (0.0, 0.0)
        vmax, wmax = ctx.params.max_linear_vel, ctx.params.max_angular_vel
        v = max(-vmax, min(vmax, v))
        w = max(-wmax, min(wmax, w))
        costmap = ctx.local_costmap
        if costmap is not None and v != 0.0:
            b = ctx.params.behavior
            horizon = float(b["projection_time"])
            dt = float(b["simulation_time_step"])
            pose = ctx.local_pose()
            poses = arc_poses(pose, v, w, horizon, dt)
            motion = poses[:, 2] if v > 0.0 else poses[:, 2] + math.pi
            radius = self._footprint_radius(ctx)
            hits = np.nonzero(footprint_in_collision(costmap, poses[:, 0], poses[:, 1], radius, motion))[0]
            if len(hits):
                first = int(hits[0])
                scale = 0.0 if first == 0 else (first * dt) / horizon
                v, w = v * scale, w * scale
        self.last_command = (v, w)
        ctx.send_velocity(v, w)

    def feedback(self) -> dict[str, Any]:
        return {"current_teleop_duration": self.elapsed()}
