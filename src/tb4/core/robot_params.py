"""The robot's parameters, one home: src/tb4/params/robot.yaml, validated into a frozen RobotParams.

Every default the simulator, the navigation core, the viewer and the pictures use for the robot (its radius
above all) is read from here; a user file or overrides given to load_robot_params change only the keys they name.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

from tb4.config import ConfigError, as_float, as_int, check_keys, load_yaml

__all__ = [
    "ROBOT_PARAMS_PATH",
    "DriveParams",
    "OdometryParams",
    "LidarParams",
    "BatteryParams",
    "DockParams",
    "Create3Params",
    "RobotParams",
    "load_robot_params",
    "default_robot_params",
    "robot_radius",
]

ROBOT_PARAMS_PATH = Path(__file__).resolve().parent.parent / "params" / "robot.yaml"


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


def robot_radius() -> float:
    """The robot's circular footprint radius (m): robot.yaml's drive.radius, the default of every radius."""
    return default_robot_params().drive.radius
