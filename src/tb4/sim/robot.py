"""The simulated TurtleBot 4 base: differential-drive kinematics and wheel odometry.

A Create 3 takes (v, w) commands, clamps them to its hardware limits, ramps the wheel speeds with bounded
acceleration and stops when commands stop arriving. Motion inside one physics step is the exact circular arc
of a unicycle at constant (v, w), so simulated paths match closed-form arcs whatever the step size.
Its parameters (src/tb4/params/robot.yaml) are loaded by tb4.core.robot_params.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from typing import Any

import numpy as np

from tb4.core.geometry import rewrap, wrap_angle
from tb4.core.robot_params import DriveParams, OdometryParams

__all__ = [
    "Odometry",
    "check_command",
    "DiffDrive",
    "OdometryIntegrator",
]


@dataclass(frozen=True)
class Odometry:
    """Wheel odometry: pose in the odom frame (the robot's start pose) and measured body velocities."""

    x: float
    y: float
    yaw: float
    v: float
    w: float


def check_command(v: Any, w: Any, drive: DriveParams) -> tuple[bool, str, float, float]:
    """Validate a velocity command: (ok, reason, v_clamped, w_clamped). Never raises, whatever the input."""
    if not (type(v) is float and type(w) is float):  # fast path for the usual case
        for name, value in (("linear", v), ("angular", w)):
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                return (False, f"{name} velocity is not a number: {value!r}", 0.0, 0.0)
    try:
        vf, wf = float(v), float(w)
    except OverflowError:
        return (False, "velocity command is absurd: too large for a float", 0.0, 0.0)
    except (TypeError, ValueError):
        return (False, f"velocity command cannot be read as numbers: ({v!r}, {w!r})", 0.0, 0.0)
    if not (math.isfinite(vf) and math.isfinite(wf)):
        return (False, f"velocity command is not finite: ({vf}, {wf})", 0.0, 0.0)
    if abs(vf) > drive.absurd_linear_speed or abs(wf) > drive.absurd_angular_speed:
        return (False, f"velocity command is absurd: ({vf}, {wf})", 0.0, 0.0)
    vmax, wmax = drive.max_linear_speed, drive.max_angular_speed
    vc = min(max(vf, -vmax), vmax)
    wc = min(max(wf, -wmax), wmax)
    reason = "ok" if (vc == vf and wc == wf) else f"clamped to hardware limits ({vc:.3f} m/s, {wc:.3f} rad/s)"
    return (True, reason, vc, wc)


class DiffDrive:
    """Commanded and actual body velocities of the base: clamping, command timeout and acceleration ramps."""

    __slots__ = ("params", "target_v", "target_w", "v", "w", "last_command_time")

    def __init__(self, params: DriveParams) -> None:
        self.params = params
        self.target_v = 0.0
        self.target_w = 0.0
        self.v = 0.0
        self.w = 0.0
        self.last_command_time = -math.inf

    def command(self, v: Any, w: Any, time: float) -> tuple[bool, str]:
        """Validate, clamp and hold a command from `time` on."""
        ok, reason, vc, wc = check_command(v, w, self.params)
        if ok:
            self.set_target(vc, wc, time)
        return (ok, reason)

    def set_target(self, v: float, w: float, time: float) -> None:
        """Hold an already validated and clamped command from `time` on."""
        self.target_v, self.target_w, self.last_command_time = v, w, time

    def stop(self) -> None:
        """Drop the current command (the ramp still decelerates the wheels)."""
        self.target_v = self.target_w = 0.0

    def halt(self) -> None:
        """Wheels stopped at once (a bump)."""
        self.v = self.w = 0.0

    def update(self, time: float, dt: float, enabled: bool = True) -> tuple[float, float]:
        """Velocities for the step starting at `time`: the target (or 0 when stale/disabled) through the ramps."""
        p = self.params
        if not enabled or time - self.last_command_time > p.command_timeout + 1e-9:
            self.target_v = self.target_w = 0.0
        dv = p.max_linear_accel * dt
        dw = p.max_angular_accel * dt
        self.v = min(max(self.target_v, self.v - dv), self.v + dv)
        self.w = min(max(self.target_w, self.w - dw), self.w + dw)
        return (self.v, self.w)


class OdometryIntegrator:
    """Wheel odometry in the frame of the start pose: integrates each executed motion, optionally with drift.

    Noise is a per-run scale error (drawn once) plus per-step relative noise, all from the generator given,
    so a seed reproduces the same drift. Teleports (set_pose) do not move odometry, as on a real robot.
    """

    _BLOCK = 4096

    def __init__(self, params: OdometryParams, rng: np.random.Generator | None = None) -> None:
        self.params = params
        self.rng = rng
        self.x = self.y = self.yaw = 0.0
        self.v = self.w = 0.0
        self._lin_scale = 1.0
        self._ang_scale = 1.0
        self._noise_list: list[list[float]] = []
        self._i = 0
        if rng is not None:
            self._lin_scale += float(rng.normal(0.0, params.linear_scale_stddev))
            self._ang_scale += float(rng.normal(0.0, params.angular_scale_stddev))

    def _next_noise(self) -> tuple[float, float, float]:
        """(linear, angular, slip-per-m/s^2) relative noise for one step, drawn in blocks for speed."""
        if self._i >= len(self._noise_list):
            assert self.rng is not None
            p = self.params
            sd = np.array([p.linear_noise_stddev, p.angular_noise_stddev, p.accel_slip_stddev])
            self._noise_list = (self.rng.normal(0.0, 1.0, size=(self._BLOCK, 3)) * sd).tolist()
            self._i = 0
        n = self._noise_list[self._i]
        self._i += 1
        return (n[0], n[1], n[2])

    def update(
        self,
        before: tuple[float, float, float],
        after: tuple[float, float, float],
        dt: float,
        accel: float = 0.0,
        spin: float = 0.0,
    ) -> None:
        """Add the motion from pose `before` to pose `after` (map frame) done in dt seconds.

        With noise, wheel slip adds to it: relative noise growing with the wheel acceleration `accel` (m/s^2),
        and, while a bump holds the robot, a share of `spin` (m the wheels were commanded to roll)."""
        dx, dy = after[0] - before[0], after[1] - before[1]
        c, s = math.cos(before[2]), math.sin(before[2])
        fx, fy = c * dx + s * dy, -s * dx + c * dy  # displacement in the robot frame at `before`
        dth = wrap_angle(after[2] - before[2])
        if self.rng is not None and (fx or fy or dth or spin):
            nl, na, ns = self._next_noise()
            k = self._lin_scale + nl + ns * abs(accel)
            fx, fy = fx * k, fy * k
            fx += spin * self.params.bump_slip_fraction
            dth *= self._ang_scale + na
        co, so = math.cos(self.yaw), math.sin(self.yaw)
        self.x += co * fx - so * fy
        self.y += so * fx + co * fy
        self.yaw = wrap_angle(self.yaw + dth)
        if dt > 0:
            chord = math.copysign(math.hypot(fx, fy), fx)
            half = 0.5 * dth
            arc = chord * half / math.sin(half) if abs(half) > 1e-9 else chord  # arc length from its chord
            self.v = arc / dt
            self.w = dth / dt

    def at_rest(self) -> bool:
        """Whether the last step was a still one (velocities zero): another changes only the heading's last bits."""
        return self.v == 0.0 and self.w == 0.0

    def rest(self, steps: int) -> None:
        """`steps` still physics steps (at_rest() held), the same to the last bit as `update` with no motion."""
        self.yaw = rewrap(self.yaw, steps)

    def reading(self) -> Odometry:
        return Odometry(self.x, self.y, self.yaw, self.v, self.w)
