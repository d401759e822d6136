"""Navigation parameters: src/tb4/params/nav2.yaml (upstream Nav2 names) loaded, validated and flattened.

The shipped YAML is the schema: a user file may only use keys that exist there, with values of the same
kind, so a misspelt key is reported with the file, the full key path and a "did you mean" hint.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tb4.config import ConfigError, as_bool, as_float, as_int, check_keys, load_yaml
from tb4.core.robot_params import robot_radius

__all__ = ["NAV2_YAML", "Nav2Params", "load_nav2_params", "default_nav2_params"]

NAV2_YAML = Path(__file__).resolve().parent.parent / "params" / "nav2.yaml"

# Keys whose value must be strictly positive (everything numeric must be >= 0 unless it sits in a list).
_POSITIVE = {
    "controller_frequency",
    "desired_linear_vel",
    "lookahead_dist",
    "min_lookahead_dist",
    "max_lookahead_dist",
    "rotate_to_heading_angular_vel",
    "max_angular_accel",
    "max_linear_accel",
    "max_angular_vel",
    "resolution",
    "robot_radius",
    "width",
    "height",
    "update_frequency",
    "max_rotational_vel",
    "rotational_acc_lim",
    "replan_period",
    "regulated_linear_scaling_min_radius",
    "cost_scaling_dist",
    "movement_time_allowance",
    "simulation_time_step",
    "sigma_hit",
    "max_beams",
    "max_particles",
    "min_particles",
    "pf_err",
    "resample_interval",
}
# Keys that may be negative: docking offsets, and AMCL's laser ranges (Nav2 uses -1 for "take it from the scan").
_SIGNED = {"staging_x_offset", "staging_yaw_offset", "laser_min_range", "laser_max_range"}


def _validate(user: Any, schema: Any, source: str | Path | None, path: str) -> Any:
    """Check `user` against the default value `schema` (same shape) and return the validated value."""
    key = path or "<top>"
    leaf = path.rsplit(".", 1)[-1]
    if isinstance(schema, dict):
        if not isinstance(user, dict):
            raise ConfigError(source, key, f"expected a mapping, got {user!r}")
        check_keys(user, schema.keys(), source, prefix=f"{path}." if path else "")
        return {k: _validate(v, schema[k], source, f"{path}.{k}" if path else str(k)) for k, v in user.items()}
    if isinstance(schema, bool):
        return as_bool(user, source, key)
    if isinstance(schema, int):
        return as_int(user, source, key, minimum=1 if leaf in _POSITIVE else 0)
    if isinstance(schema, float):
        value = as_float(user, source, key, minimum=None if leaf in _SIGNED else 0.0)
        if leaf in _POSITIVE and value <= 0.0:
            raise ConfigError(source, key, f"must be > 0, got {value}")
        return value
    if isinstance(schema, list):
        if not isinstance(user, list) or len(user) != len(schema):
            raise ConfigError(source, key, f"expected a list of {len(schema)} numbers, got {user!r}")
        return [as_float(v, source, f"{key}[{i}]") for i, v in enumerate(user)]
    raise ConfigError(source, key, f"unsupported default type {type(schema).__name__}")  # pragma: no cover


def _merge(base: dict[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else copy.deepcopy(v)
    return out


@dataclass(frozen=True)
class Nav2Params:
    """The nested parameter tree plus typed accessors for the values the nav core reads."""

    tree: dict[str, Any]
    source: str

    def section(self, *keys: str) -> dict[str, Any]:
        node: Any = self.tree
        for k in keys:
            node = node[k]
        return node

    # --- node sections -------------------------------------------------------------------------------
    @property
    def bt(self) -> dict[str, Any]:
        return self.section("bt_navigator", "ros__parameters")

    @property
    def controller(self) -> dict[str, Any]:
        return self.section("controller_server", "ros__parameters")

    @property
    def rpp(self) -> dict[str, Any]:
        return self.controller["FollowPath"]

    @property
    def goal_checker(self) -> dict[str, Any]:
        return self.controller["general_goal_checker"]

    @property
    def progress_checker(self) -> dict[str, Any]:
        return self.controller["progress_checker"]

    @property
    def planner(self) -> dict[str, Any]:
        return self.section("planner_server", "ros__parameters", "GridBased")

    @property
    def behavior(self) -> dict[str, Any]:
        return self.section("behavior_server", "ros__parameters")

    @property
    def waypoint_follower(self) -> dict[str, Any]:
        return self.section("waypoint_follower", "ros__parameters")

    @property
    def amcl(self) -> dict[str, Any]:
        return self.section("amcl", "ros__parameters")

    @property
    def global_costmap(self) -> dict[str, Any]:
        return self.section("global_costmap", "global_costmap", "ros__parameters")

    @property
    def local_costmap(self) -> dict[str, Any]:
        return self.section("local_costmap", "local_costmap", "ros__parameters")

    # --- derived values -----------------------------------------------------------------------------
    @property
    def max_linear_vel(self) -> float:
        """Velocity smoother cap on |v| (the last word on what reaches the base)."""
        return float(self.section("velocity_smoother", "ros__parameters")["max_velocity"][0])

    @property
    def max_angular_vel(self) -> float:
        return float(self.section("velocity_smoother", "ros__parameters")["max_velocity"][2])

    @property
    def max_linear_accel(self) -> float:
        return float(self.section("velocity_smoother", "ros__parameters")["max_accel"][0])

    @property
    def max_angular_accel(self) -> float:
        return float(self.section("velocity_smoother", "ros__parameters")["max_accel"][2])

    @property
    def controller_period(self) -> float:
        return 1.0 / float(self.controller["controller_frequency"])

    def costmap_params(self, which: str = "global") -> Any:
        """A tb4.nav.costmap.CostmapParams for the global or the local costmap."""
        from tb4.nav.costmap import CostmapParams

        sec = self.global_costmap if which == "global" else self.local_costmap
        kwargs: dict[str, Any] = {
            "resolution": float(sec["resolution"]),
            "robot_radius": float(sec["robot_radius"]),
            "inflation_radius": float(sec["inflation_layer"]["inflation_radius"]),
            "cost_scaling_factor": float(sec["inflation_layer"]["cost_scaling_factor"]),
            "track_unknown_space": bool(sec["track_unknown_space"]),
        }
        if which == "global" and "obstacle_layer" in sec:
            layer = sec["obstacle_layer"]
            kwargs["obstacle_layer"] = bool(layer["enabled"])
            kwargs["obstacle_max_range"] = float(layer["obstacle_max_range"])
            kwargs["raytrace_max_range"] = float(layer["raytrace_max_range"])
        if which != "global":
            kwargs["width"] = float(sec["width"])
            kwargs["height"] = float(sec["height"])
            kwargs["obstacle_max_range"] = float(sec["obstacle_layer"]["obstacle_max_range"])
            kwargs["raytrace_max_range"] = float(sec["obstacle_layer"]["raytrace_max_range"])
        return CostmapParams(**kwargs)


def _check_consistency(tree: dict[str, Any], source: str) -> None:
    rpp = tree["controller_server"]["ros__parameters"]["FollowPath"]
    if not rpp["min_lookahead_dist"] <= rpp["lookahead_dist"] <= rpp["max_lookahead_dist"]:
        raise ConfigError(
            source,
            "controller_server.ros__parameters.FollowPath.lookahead_dist",
            "must lie between min_lookahead_dist and max_lookahead_dist",
        )
    for name in ("global_costmap", "local_costmap"):
        sec = tree[name][name]["ros__parameters"]
        if sec["inflation_layer"]["inflation_radius"] < sec["robot_radius"]:
            raise ConfigError(
                source,
                f"{name}.{name}.ros__parameters.inflation_layer.inflation_radius",
                "must be at least robot_radius",
            )
    amcl = tree["amcl"]["ros__parameters"]
    if amcl["min_particles"] > amcl["max_particles"]:
        raise ConfigError(source, "amcl.ros__parameters.min_particles", "must not exceed max_particles")
    vs = tree["velocity_smoother"]["ros__parameters"]
    if any(not math.isfinite(v) for v in vs["max_velocity"] + vs["max_accel"]):
        raise ConfigError(source, "velocity_smoother.ros__parameters", "velocity limits must be finite")


_DEFAULT_TREE: dict[str, Any] | None = None


def _with_robot_radius(raw: dict[str, Any]) -> dict[str, Any]:
    """Each costmap's robot_radius defaults to robot.yaml's drive.radius (the one source of the robot's size);
    nav2.yaml leaves it out, and a user file may still set it as on upstream Nav2."""
    for name in ("global_costmap", "local_costmap"):
        raw[name][name]["ros__parameters"].setdefault("robot_radius", robot_radius())
    return raw


def _defaults() -> dict[str, Any]:
    global _DEFAULT_TREE
    if _DEFAULT_TREE is None:
        raw = _with_robot_radius(load_yaml(NAV2_YAML))
        _DEFAULT_TREE = _validate(raw, raw, NAV2_YAML, "")
    return _DEFAULT_TREE


def load_nav2_params(path: str | Path | None = None, overrides: Mapping[str, Any] | None = None) -> Nav2Params:
    """Defaults from the shipped nav2.yaml, updated by a user YAML file and/or an overrides mapping."""
    defaults = _defaults()
    tree = copy.deepcopy(defaults)
    source = str(NAV2_YAML)
    if path is not None:
        user = load_yaml(path)
        tree = _merge(tree, _validate(user, defaults, path, ""))
        source = str(path)
    if overrides:
        tree = _merge(tree, _validate(dict(overrides), defaults, "<overrides>", ""))
    _check_consistency(tree, source)
    return Nav2Params(tree=tree, source=source)


def default_nav2_params() -> Nav2Params:
    return load_nav2_params()
