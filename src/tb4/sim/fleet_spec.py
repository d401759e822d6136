"""Which robots a world holds and where their docks are: the `docks:` and `robots:` keys of a world file.

A world has one dock (`dock:`) or several (`docks:`); its robots come from `robots:` (namespace, dock, start) or
from `tb4 sim --robots N`, which puts robot1..robotN on the first N docks. Docks beyond the first have no station
drawn in the map, so a fleet adds each one's station body as a static obstacle (station_obstacle).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tb4.config import ConfigError, as_int, as_pose2d, as_str, check_keys
from tb4.core.robot_params import robot_radius
from tb4.sim.obstacles import Obstacle

__all__ = [
    "RobotSpec",
    "parse_docks",
    "parse_robots",
    "robots_on_docks",
    "check_namespace",
    "station_obstacle",
]

_ROBOT_KEYS = ("namespace", "dock", "start")
# the dock station's body relative to the docked robot (tools/draw_worlds.py draws the first one in the map)
_STATION_AHEAD, _STATION_SIZE = 0.29, (0.2, 0.4)


@dataclass(frozen=True)
class RobotSpec:
    """One robot of a world: its namespace ("/robot1"), its start pose and the dock it belongs to."""

    namespace: str
    start: tuple[float, float, float]
    dock: tuple[float, float, float]


def check_namespace(text: str, source: str | Path | None, key: str) -> str:
    """'robot1' or '/robot1' -> '/robot1'; letters, digits and underscores only (ROS names)."""
    ns = str(text).strip().strip("/")
    if not ns or not all(part.isidentifier() for part in ns.split("/")):
        raise ConfigError(source, key, f"invalid namespace {text!r}: use letters, digits and underscores, e.g. robot1")
    return f"/{ns}"


def parse_docks(raw: Mapping[str, Any], source: Path) -> tuple[tuple[float, float, float], ...]:
    """`dock: [x, y, heading]` (one) or `docks: [[x, y, heading], ...]` (several; the first is the default)."""
    if ("dock" in raw) == ("docks" in raw):
        raise ConfigError(source, "dock", "give either 'dock' (one dock) or 'docks' (a list of docks)")
    if "dock" in raw:
        return (as_pose2d(raw["dock"], source, "dock"),)
    docks = raw["docks"]
    if not isinstance(docks, (list, tuple)) or not docks:
        raise ConfigError(source, "docks", f"expected a non-empty list of [x, y, heading_degrees], got {docks!r}")
    out = tuple(as_pose2d(d, source, f"docks[{i}]") for i, d in enumerate(docks))
    for i, a in enumerate(out):
        for j in range(i):
            if math.hypot(a[0] - out[j][0], a[1] - out[j][1]) < 4.0 * robot_radius():
                raise ConfigError(source, f"docks[{i}]", f"too close to docks[{j}]: two docked robots would touch")
    return out


def parse_robots(raw: Any, source: Path, docks: Sequence[tuple[float, float, float]]) -> tuple[RobotSpec, ...]:
    """`robots:` entries {namespace, dock: index into docks (default: the entry's own index), start: 'docked'
    (default) or [x, y, heading]}. Namespaces are unique, no two robots share a dock, no two start overlapping."""
    if raw is None:
        return ()
    if not isinstance(raw, (list, tuple)):
        raise ConfigError(source, "robots", f"expected a list of robots ({{namespace, dock, start}}), got {raw!r}")
    robots: list[RobotSpec] = []
    dock_owner: dict[int, str] = {}
    for i, spec in enumerate(raw):
        key = f"robots[{i}]"
        if not isinstance(spec, Mapping):
            raise ConfigError(source, key, f"expected a mapping with namespace, dock and start, got {spec!r}")
        check_keys(spec, _ROBOT_KEYS, source, prefix=f"{key}.", required=("namespace",))
        ns = check_namespace(as_str(spec["namespace"], source, f"{key}.namespace"), source, f"{key}.namespace")
        if any(r.namespace == ns for r in robots):
            raise ConfigError(source, f"{key}.namespace", f"namespace {ns!r} is used by another robot")
        default_dock = i if i < len(docks) else 0
        index = as_int(spec.get("dock", default_dock), source, f"{key}.dock", minimum=0, maximum=len(docks) - 1)
        start_raw = spec.get("start", "docked")
        if start_raw == "docked":
            if index in dock_owner:
                raise ConfigError(source, f"{key}.dock", f"dock {index} is taken by {dock_owner[index]!r}")
            dock_owner[index] = ns
            start = docks[index]
        elif isinstance(start_raw, str):
            raise ConfigError(
                source, f"{key}.start", f"expected 'docked' or [x, y, heading_degrees], got {start_raw!r}"
            )
        else:
            start = as_pose2d(start_raw, source, f"{key}.start")
        for other in robots:
            if math.hypot(start[0] - other.start[0], start[1] - other.start[1]) < 2.0 * robot_radius():
                raise ConfigError(source, f"{key}.start", f"overlaps robot {other.namespace!r} at its start")
        robots.append(RobotSpec(ns, start, docks[index]))
    return tuple(robots)


def robots_on_docks(
    docks: Sequence[tuple[float, float, float]], count: int, world: str = "the world"
) -> tuple[RobotSpec, ...]:
    """`--robots N`: robot1..robotN docked on the first N docks."""
    if not (isinstance(count, int) and count >= 1):
        raise ValueError(f"--robots must be a whole number of at least 1, got {count!r}")
    if count > len(docks):
        raise ValueError(
            f"{world} has {len(docks)} dock(s); --robots {count} needs {count} "
            "(list more under 'docks:' in the world file, or give robots their own 'start' under 'robots:')"
        )
    return tuple(RobotSpec(f"/robot{i + 1}", docks[i], docks[i]) for i in range(count))


def station_obstacle(dock: tuple[float, float, float]) -> Obstacle:
    """The dock station's body just ahead of a robot docked at `dock` (a static box the lidar sees)."""
    x, y, yaw = dock
    cx, cy = x + _STATION_AHEAD * math.cos(yaw), y + _STATION_AHEAD * math.sin(yaw)
    return Obstacle(shape="box", size=_STATION_SIZE, yaw=yaw, path=((cx, cy),))
