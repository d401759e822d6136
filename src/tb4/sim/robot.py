"""The simulated TurtleBot 4 base: parameters, differential-drive kinematics and wheel odometry.

A Create 3 takes (v, w) commands, clamps them to its hardware limits, ramps the wheel speeds with bounded
acceleration and stops when commands stop arriving. Motion inside one physics step is the exact circular arc
of a unicycle at constant (v, w), so simulated paths match closed-form arcs whatever the step size.
All defaults live in src/tb4/params/robot.yaml and are validated here into a frozen RobotParams.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from tb4.config import ConfigError, as_float, as_int, check_keys, load_yaml

__all__ = [
    "ROBOT_PARAMS_PATH",
    "Pose2D",
    "Odometry",
    "DriveParams",
    "OdometryParams",
    "LidarParams",
    "BatteryParams",
    "DockParams",
    "Create3Params",
    "RobotParams",
    "load_robot_params",
    "default_robot_params",
    "wrap_angle",
    "arc_pose",
    "check_command",
    "DiffDrive",
    "OdometryIntegrator",
]

ROBOT_PARAMS_PATH = Path(__file__).resolve().parent.parent / "params" / "robot.yaml"


@dataclass(frozen=True)
class Pose2D:
    """A planar pose in metres and radians (yaw counter-clockwise from +x)."""

    x: float
    y: float
    yaw: float


@dataclass(frozen=True)
class Odometry:
    """Wheel odometry: pose in the odom frame (the robot's start pose) and measured body velocities."""

    x: float
    y: float
    yaw: float
    v: float
    w: float


def _num(lo: float | None = None, hi: float | None = None, *, positive: bool = False) -> Any:
    """Field marker carrying the bounds used when validating the YAML value."""
    return field(metadata={"min": lo, "max": hi, "positive": positive})


@dataclass(frozen=True)
class DriveParams:
    radius: float = _num(positive=True)
    max_linear_speed: float = _num(positive=True)
    max_angular_speed: float = _num(positive=True)
    max_linear_accel: float = _num(positive=True)
    max_angular_accel: float = _num(positive=True)
    command_timeout: float = _num(positive=True)
    absurd_linear_speed: float = _num(positive=True)
    absurd_angular_speed: float = _num(positive=True)
    collision_min_step: float = _num(0.01, 1.0)


@dataclass(frozen=True)
class OdometryParams:
    linear_scale_stddev: float = _num(0.0, 0.5)
    angular_scale_stddev: float = _num(0.0, 0.5)
    linear_noise_stddev: float = _num(0.0, 1.0)
    angular_noise_stddev: float = _num(0.0, 1.0)
    accel_slip_stddev: float = _num(0.0, 1.0)
    bump_slip_fraction: float = _num(0.0, 1.0)


@dataclass(frozen=True)
class LidarParams:
    beams: int = _num(1, 100000)
    range_min: float = _num(0.0)
    range_max: float = _num(positive=True)
    rate_hz: float = _num(positive=True)
    noise_stddev: float = _num(0.0, 1.0)
    dropout_probability: float = _num(0.0, 1.0)


@dataclass(frozen=True)
class BatteryParams:
    capacity_wh: float = _num(positive=True)
    nominal_voltage: float = _num(positive=True)
    empty_voltage: float = _num(positive=True)
    full_voltage: float = _num(positive=True)
    base_power: float = _num(0.0)
    linear_power: float = _num(0.0)
    angular_power: float = _num(0.0)
    charge_time: float = _num(positive=True)
    temperature: float = _num(-40.0, 100.0)

    @property
    def capacity_ah(self) -> float:
        return self.capacity_wh / self.nominal_voltage


@dataclass(frozen=True)
class DockParams:
    visible_distance: float = _num(positive=True)
    visible_half_angle: float = _num(0.0, 180.0)
    station_offset: float = _num(positive=True)
    docked_distance: float = _num(positive=True)
    docked_yaw: float = _num(positive=True)
    action_timeout: float = _num(positive=True)
    approach_speed: float = _num(positive=True)
    undock_distance: float = _num(positive=True)
    undock_speed: float = _num(positive=True)
    turn_speed: float = _num(positive=True)


@dataclass(frozen=True)
class Create3Params:
    """The Create 3 base beyond its drive: wheels, IR and cliff sensors, safety limits (see robot.yaml)."""

    wheel_base: float = _num(positive=True)
    wheel_radius: float = _num(positive=True)
    ticks_per_rev: float = _num(positive=True)
    ir_angles: tuple[float, ...] = _num(-180.0, 180.0)
    ir_range: float = _num(positive=True)
    ir_max_intensity: float = _num(positive=True)
    cliff_angles: tuple[float, ...] = _num(-180.0, 180.0)
    cliff_radius: float = _num(positive=True)
    backup_limit: float = _num(positive=True)
    backup_warning: float = _num(0.0)
    stall_time: float = _num(positive=True)
    kidnap_lift_time: float = _num(positive=True)
    ir_opcode_distance: float = _num(positive=True)


@dataclass(frozen=True)
class RobotParams:
    """Everything the simulator knows about the robot; build it with load_robot_params()."""

    drive: DriveParams
    odometry: OdometryParams
    lidar: LidarParams
    battery: BatteryParams
    dock: DockParams
    create3: Create3Params


_SECTIONS: dict[str, type] = {
    "drive": DriveParams,
    "odometry": OdometryParams,
    "lidar": LidarParams,
    "battery": BatteryParams,
    "dock": DockParams,
    "create3": Create3Params,
}


def _parse_section(cls: type, raw: Mapping[str, Any], source: str | Path, section: str) -> Any:
    names = [f.name for f in dataclasses.fields(cls)]
    check_keys(raw, names, source, prefix=f"{section}.", required=names)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        key = f"{section}.{f.name}"
        meta = f.metadata
        if f.type in ("int", int):
            values[f.name] = as_int(raw[f.name], source, key, minimum=meta["min"], maximum=meta["max"])
        elif str(f.type).startswith("tuple"):
            items = raw[f.name]
            if not isinstance(items, (list, tuple)) or not items:
                raise ConfigError(source, key, f"expected a non-empty list of numbers, got {items!r}")
            values[f.name] = tuple(
                as_float(v, source, f"{key}[{i}]", minimum=meta["min"], maximum=meta["max"])
                for i, v in enumerate(items)
            )
        else:
            val = as_float(raw[f.name], source, key, minimum=meta["min"], maximum=meta["max"])
            if meta["positive"] and val <= 0.0:
                raise ConfigError(source, key, f"must be > 0, got {val}")
            values[f.name] = val
    return cls(**values)


def _check_consistency(p: RobotParams, source: str | Path) -> None:
    if p.lidar.range_min >= p.lidar.range_max:
        raise ConfigError(source, "lidar.range_min", f"must be below lidar.range_max ({p.lidar.range_max})")
    if p.battery.empty_voltage >= p.battery.full_voltage:
        raise ConfigError(source, "battery.empty_voltage", f"must be below full_voltage ({p.battery.full_voltage})")


def load_robot_params(path: str | Path | None = None, overrides: Mapping[str, Any] | None = None) -> RobotParams:
    """Defaults from robot.yaml, then the sections/keys of an optional user file, then `overrides`.

    User files and overrides are partial: `{"lidar": {"beams": 720}}` changes just that key.
    """
    merged: dict[str, dict[str, Any]] = {k: dict(v) for k, v in _default_raw().items()}
    layers: list[tuple[Mapping[str, Any], str | Path]] = []
    if path is not None:
        layers.append((load_yaml(path), path))
    if overrides is not None:
        layers.append((overrides, "<overrides>"))
    for layer, source in layers:
        check_keys(layer, _SECTIONS, source)
        for section, values in layer.items():
            if not isinstance(values, Mapping):
                raise ConfigError(source, section, f"expected a mapping of parameters, got {values!r}")
            check_keys(values, merged[section], source, prefix=f"{section}.")
            merged[section].update(values)
    source = path if path is not None else ("<overrides>" if overrides is not None else ROBOT_PARAMS_PATH)
    parsed = {name: _parse_section(cls, merged[name], source, name) for name, cls in _SECTIONS.items()}
    params = RobotParams(**parsed)
    _check_consistency(params, source)
    return params


@lru_cache(maxsize=1)
def _default_raw() -> dict[str, dict[str, Any]]:
    raw = load_yaml(ROBOT_PARAMS_PATH)
    check_keys(raw, _SECTIONS, ROBOT_PARAMS_PATH, required=_SECTIONS)
    return raw


@lru_cache(maxsize=1)
def default_robot_params() -> RobotParams:
    """The packaged defaults (validated once, then shared: the dataclasses are frozen)."""
    return load_robot_params()


def wrap_angle(a: float) -> float:
    """Angle in [-pi, pi)."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def arc_pose(x: float, y: float, yaw: float, v: float, w: float, t: float) -> tuple[float, float, float]:
    """Pose after driving t seconds at constant (v, w): the exact unicycle arc (a straight line when w == 0)."""
    if abs(w) < 1e-12:
        return (x + v * t * math.cos(yaw), y + v * t * math.sin(yaw), yaw)
    yaw2 = yaw + w * t
    r = v / w
    return (x + r * (math.sin(yaw2) - math.sin(yaw)), y - r * (math.cos(yaw2) - math.cos(yaw)), wrap_angle(yaw2))


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

    def reading(self) -> Odometry:
        return Odometry(self.x, self.y, self.yaw, self.v, self.w)
