"""Simulated worlds: a map plus the dock, the start pose, named destinations and extra obstacles.

A world file (``worlds/<name>.yaml``) points at a map_server map and adds what a map cannot hold: where the dock
is, where the robot starts, places a user (or a language interpreter) can name, and obstacles that are NOT in the
map, so the robot has to discover them with its lidar, some of them moving. Every key is validated at load so a
typo is reported with the file, the key and a suggestion, not as a crash deep inside the simulator.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tb4.config import ConfigError, as_file, as_float, as_pose2d, as_str, as_xy, check_keys, load_yaml, require
from tb4.core.maps import OccupancyMap, load_map
from tb4.sim.fleet_spec import RobotSpec, parse_docks, parse_robots
from tb4.sim.obstacles import Obstacle, static_mask

__all__ = [
    "WORLDS_DIR",
    "DEFAULT_WORLD",
    "Destination",
    "parse_destinations",
    "World",
    "load_world",
    "available_worlds",
]

WORLDS_DIR: Path = Path(__file__).resolve().parent.parent / "worlds"
DEFAULT_WORLD = "warehouse"

_WORLD_KEYS = (
    "name",
    "map",
    "dock",
    "docks",
    "robots",
    "start",
    "destinations",
    "obstacles",
    "datum",
    "route_graph",
    "cliffs",
)
_DESTINATION_KEYS = ("position", "heading", "description", "aliases")
_OBSTACLE_KEYS = ("shape", "position", "path", "radius", "size", "heading", "speed", "mode")
_SHAPES = ("circle", "box")
_MODES = ("pingpong", "loop")
_MAP_SUFFIX = "_map"
_LETHAL = 65  # grid values from here up are occupied (OccupancyMap.occupied_mask)


@dataclass(frozen=True)
class Destination:
    """A named place (pose in the map frame, yaw in radians) with words a user may call it by."""

    name: str
    x: float
    y: float
    yaw: float
    description: str = ""
    aliases: tuple[str, ...] = ()


@dataclass
class World:
    """A loaded world. `dock` is the pose of the docked robot; the station body is just ahead of it."""

    name: str
    map: OccupancyMap
    map_path: Path
    source: Path
    dock: tuple[float, float, float]
    start: tuple[float, float, float]
    destinations: dict[str, Destination] = field(default_factory=dict)
    obstacles: tuple[Obstacle, ...] = ()
    datum: tuple[float, float, float] | None = None  # GPS of the map origin: latitude, longitude, heading (deg)
    route_graph: Path | None = None  # Nav2 route server GeoJSON graph file
    cliffs: tuple[Obstacle, ...] = ()  # floor drops (boxes/circles): the cliff sensors see them, the lidar does not
    docks: tuple[tuple[float, float, float], ...] = ()  # every dock; the first is `dock` (empty: just `dock`)
    robots: tuple[RobotSpec, ...] = ()  # the fleet the world file lists (empty: one robot, no namespace)

    @property
    def all_docks(self) -> tuple[tuple[float, float, float], ...]:
        return self.docks or (self.dock,)

    @property
    def static_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if not o.moving)

    @property
    def moving_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if o.moving)

    def static_obstacle_mask(self) -> np.ndarray:
        """Cells that never move: the map's occupied or unknown cells plus the static extra obstacles."""
        return static_mask(self.map, self.static_obstacles)

    def find_destination(self, name: str) -> Destination | None:
        """A destination by name or alias, ignoring case and surrounding blanks."""
        key = " ".join(name.lower().split())
        for dest in self.destinations.values():
            if key == dest.name.lower() or key in (a.lower() for a in dest.aliases):
                return dest
        return None


def available_worlds() -> list[str]:
    """Names of the worlds shipped in WORLDS_DIR (world files, not their `*_map.yaml` maps)."""
    if not WORLDS_DIR.is_dir():
        return []
    return sorted(p.stem for p in WORLDS_DIR.glob("*.yaml") if not p.stem.endswith(_MAP_SUFFIX))


def _resolve(name_or_path: str | Path) -> Path:
    if isinstance(name_or_path, Path):
        return name_or_path
    text = str(name_or_path).strip()
    if not text:
        raise ConfigError(None, "world", f"expected a world name or a world file; available worlds: {_known()}")
    looks_like_path = text.endswith((".yaml", ".yml")) or "/" in text or "\\" in text
    if looks_like_path:
        path = Path(text).expanduser()
        if path.exists() and not path.is_file():  # a directory, a device (/dev/zero), a pipe: never read one
            raise ConfigError(None, "world", f"{text!r} is not a regular file")
        return path
    candidate = WORLDS_DIR / f"{text}.yaml"
    if text in available_worlds() and candidate.is_file():
        return candidate
    close = difflib.get_close_matches(text, available_worlds(), n=1, cutoff=0.5)
    hint = f"; did you mean '{close[0]}'?" if close else ""
    raise ConfigError(None, "world", f"unknown world {text!r}{hint} (available worlds: {_known()})")


def _known() -> str:
    return ", ".join(available_worlds()) or "none found in " + str(WORLDS_DIR)


def load_world(name_or_path: str | Path) -> World:
    """Load a shipped world by name (e.g. "depot") or any world file by path, validating every key."""
    path = _resolve(name_or_path)
    raw = load_yaml(path)
    check_keys(raw, _WORLD_KEYS, path, required=("map",))

    name = as_str(raw["name"], path, "name") if "name" in raw else path.stem
    map_path = as_file(require(raw, "map", path), path, "map", "map file")
    grid = load_map(map_path)

    obstacles = _parse_obstacles(raw.get("obstacles", []), path)
    for i, obs in enumerate(obstacles):
        for j, (px, py) in enumerate(obs.path):
            if not grid.in_bounds(px, py):
                key = f"obstacles[{i}].path[{j}]" if obs.moving else f"obstacles[{i}].position"
                raise ConfigError(path, key, f"point ({px:g}, {py:g}) is outside the map")
    static = tuple(o for o in obstacles if not o.moving)
    docks = parse_docks(raw, path)
    dock = docks[0]
    for i, d in enumerate(docks):
        key, what = (f"docks[{i}]", f"dock {i}") if "docks" in raw else ("dock", "the dock pose")
        _check_pose_free(grid, static, d[0], d[1], path, key, what)
    robots = parse_robots(raw.get("robots"), path, docks)
    for i, robot in enumerate(robots):
        _check_pose_free(grid, static, robot.start[0], robot.start[1], path, f"robots[{i}].start", robot.namespace)
    start_raw = raw.get("start", "docked")
    if start_raw == "docked":
        start = dock
    elif isinstance(start_raw, str):
        raise ConfigError(path, "start", f"expected 'docked' or [x, y, heading_degrees], got {start_raw!r}")
    else:
        start = as_pose2d(start_raw, path, "start")

    if start is not dock:
        _check_pose_free(grid, static, start[0], start[1], path, "start", "the start pose")
    destinations = parse_destinations(raw.get("destinations", {}), path, grid, static)
    datum = _parse_datum(raw["datum"], path) if "datum" in raw else None
    route_graph = None
    if "route_graph" in raw:
        route_graph = as_file(raw["route_graph"], path, "route_graph", "route graph file")
    cliffs = _parse_cliffs(raw.get("cliffs", []), path)
    return World(
        name=name,
        map=grid,
        map_path=map_path,
        source=path,
        dock=dock,
        start=start,
        destinations=destinations,
        obstacles=obstacles,
        datum=datum,
        route_graph=route_graph,
        cliffs=cliffs,
        docks=docks,
        robots=robots,
    )


def _parse_datum(raw: Any, source: Path) -> tuple[float, float, float]:
    """[latitude, longitude, heading]: degrees; heading of the map's +x axis, counter-clockwise from east."""
    if not isinstance(raw, (list, tuple)) or len(raw) != 3:
        raise ConfigError(source, "datum", f"expected [latitude, longitude, heading_degrees], got {raw!r}")
    lat = as_float(raw[0], source, "datum[0]", minimum=-89.9, maximum=89.9)
    lon = as_float(raw[1], source, "datum[1]", minimum=-180.0, maximum=180.0)
    return (lat, lon, as_float(raw[2], source, "datum[2]"))


def _parse_cliffs(raw: Any, source: Path) -> tuple[Obstacle, ...]:
    """`cliffs:` regions where the floor drops, written like static obstacles (shape, position, size/radius)."""
    if raw is None:
        return ()
    if not isinstance(raw, (list, tuple)):
        raise ConfigError(source, "cliffs", f"expected a list of regions, got {raw!r}")
    out = []
    for i, spec in enumerate(raw):
        if isinstance(spec, Mapping) and "path" in spec:
            raise ConfigError(source, f"cliffs[{i}].path", "cliffs do not move: give a 'position'")
        out.append(_parse_obstacle(spec, source, f"cliffs[{i}]"))
    return tuple(out)


def _check_pose_free(
    grid: OccupancyMap, static: tuple[Obstacle, ...], x: float, y: float, source: Path, key: str, what: str
) -> None:
    """Refuse a pose off the map, in a wall, in unknown space or inside a static obstacle."""
    if not grid.in_bounds(x, y):
        lo_x, lo_y, hi_x, hi_y = grid.bounds
        raise ConfigError(
            source, key, f"{what} ({x:g}, {y:g}) is outside the map (x {lo_x:g}..{hi_x:g}, y {lo_y:g}..{hi_y:g})"
        )
    value = grid.value_at(x, y)
    if value < 0 or value >= _LETHAL:
        kind = "unknown space" if value < 0 else "an occupied cell (a wall or object)"
        raise ConfigError(source, key, f"{what} ({x:g}, {y:g}) is in {kind} of the map; move it into free space")
    for i, obs in enumerate(static):
        if bool(obs.contains(x, y)):
            raise ConfigError(source, key, f"{what} ({x:g}, {y:g}) is inside static obstacle #{i} ({obs.shape})")


def parse_destinations(
    raw: Any, source: Path, grid: OccupancyMap | None, static: tuple[Obstacle, ...] = ()
) -> dict[str, Destination]:
    """The `destinations:` mapping of a world (or of gpt_node's destinations file): name -> position, heading,
    description, aliases. With a map, each position must lie in its free space."""
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise ConfigError(source, "destinations", f"expected a mapping of name -> {{position, heading}}, got {raw!r}")
    result: dict[str, Destination] = {}
    taken: dict[str, str] = {}
    for name, spec in raw.items():
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(source, "destinations", f"destination names must be non-empty strings, got {name!r}")
        key = f"destinations.{name}"
        if not isinstance(spec, Mapping):
            raise ConfigError(source, key, f"expected a mapping with position and heading, got {spec!r}")
        check_keys(spec, _DESTINATION_KEYS, source, prefix=f"{key}.", required=("position",))
        x, y = as_xy(spec["position"], source, f"{key}.position")
        yaw = math.radians(as_float(spec.get("heading", 0.0), source, f"{key}.heading"))
        description = spec.get("description", "")
        if description != "":
            description = as_str(description, source, f"{key}.description")
        aliases_raw = spec.get("aliases", [])
        if not isinstance(aliases_raw, (list, tuple)):
            raise ConfigError(source, f"{key}.aliases", f"expected a list of names, got {aliases_raw!r}")
        aliases = tuple(as_str(a, source, f"{key}.aliases[{i}]") for i, a in enumerate(aliases_raw))
        for word in (name, *aliases):
            norm = " ".join(word.lower().split())
            if norm in taken and taken[norm] != name:
                raise ConfigError(source, key, f"name or alias {word!r} is already used by destination {taken[norm]!r}")
            taken[norm] = name
        if grid is not None:
            _check_pose_free(grid, static, x, y, source, f"{key}.position", f"destination {name!r}")
        result[name] = Destination(name=name, x=x, y=y, yaw=yaw, description=description, aliases=aliases)
    return result


def _parse_obstacles(raw: Any, source: Path) -> tuple[Obstacle, ...]:
    if raw is None:
        return ()
    if not isinstance(raw, (list, tuple)):
        raise ConfigError(source, "obstacles", f"expected a list of obstacles, got {raw!r}")
    return tuple(_parse_obstacle(spec, source, f"obstacles[{i}]") for i, spec in enumerate(raw))


def _parse_obstacle(spec: Any, source: Path, key: str) -> Obstacle:
    if not isinstance(spec, Mapping):
        raise ConfigError(source, key, f"expected a mapping (shape, position or path, ...), got {spec!r}")
    check_keys(spec, _OBSTACLE_KEYS, source, prefix=f"{key}.", required=("shape",))
    shape = spec["shape"]
    if shape not in _SHAPES:
        close = difflib.get_close_matches(str(shape), _SHAPES, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise ConfigError(source, f"{key}.shape", f"expected circle or box, got {shape!r}{hint}")
    has_position, has_path = "position" in spec, "path" in spec
    if has_position == has_path:
        raise ConfigError(source, key, "give either 'position' (a static obstacle) or 'path' (a moving one)")
    if has_position:
        path: tuple[tuple[float, float], ...] = (as_xy(spec["position"], source, f"{key}.position"),)
        for moving_key in ("speed", "mode"):
            if moving_key in spec:
                raise ConfigError(source, f"{key}.{moving_key}", "only moving obstacles (with a 'path') take this key")
        speed, mode = 0.0, "pingpong"
    else:
        pts = spec["path"]
        if not isinstance(pts, (list, tuple)) or len(pts) < 2:
            raise ConfigError(source, f"{key}.path", f"expected a list of at least two [x, y] points, got {pts!r}")
        path = tuple(as_xy(p, source, f"{key}.path[{i}]") for i, p in enumerate(pts))
        speed = as_float(require(spec, "speed", source, f"{key}."), source, f"{key}.speed", minimum=0.0, maximum=5.0)
        if speed <= 0.0:
            raise ConfigError(source, f"{key}.speed", "a moving obstacle needs a speed above 0 m/s")
        mode = spec.get("mode", "pingpong")
        if mode not in _MODES:
            raise ConfigError(source, f"{key}.mode", f"expected pingpong or loop, got {mode!r}")
        if shape != "circle":
            raise ConfigError(source, f"{key}.shape", "moving obstacles must be circles")
    if shape == "circle":
        for box_key in ("size", "heading"):
            if box_key in spec:
                raise ConfigError(source, f"{key}.{box_key}", "only box obstacles take this key (circles use radius)")
        radius = as_float(require(spec, "radius", source, f"{key}."), source, f"{key}.radius", minimum=0.01)
        return Obstacle(shape="circle", radius=radius, path=path, speed=speed, mode=mode)
    if "radius" in spec:
        raise ConfigError(source, f"{key}.radius", "only circle obstacles take a radius (boxes use size)")
    size_raw = require(spec, "size", source, f"{key}.")
    length, width = as_xy(size_raw, source, f"{key}.size")
    if length < 0.01 or width < 0.01:
        raise ConfigError(source, f"{key}.size", f"box sides must be at least 0.01 m, got {size_raw!r}")
    yaw = math.radians(as_float(spec.get("heading", 0.0), source, f"{key}.heading"))
    return Obstacle(shape="box", size=(length, width), yaw=yaw, path=path)
