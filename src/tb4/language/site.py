"""Where gpt_node may send the robot: named destinations, the map goals are checked against, the dock.

A Site comes from a destinations file of its own (for a real robot: its saved map and the places people name) or
from a simulator world (one source among others, not the only one). The destinations file:

    name: lab                       # optional (default: the file's stem)
    map: lab_map.yaml               # optional map_server map; without one goals are only checked for finiteness
    dock: [0.0, 0.0, 0.0]           # optional docked pose [x, y, heading_degrees]: adds the 'dock' destination
    destinations:                   # as in world files: position, heading, description, aliases
      kitchen: {position: [3.0, 1.5], heading: 90, description: "the kitchen", aliases: [coffee]}
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from tb4.config import ConfigError, as_file, as_pose2d, as_str, check_keys, load_yaml
from tb4.core.geometry import Pose
from tb4.core.maps import OccupancyMap, load_map
from tb4.sim.world import Destination, World, load_world, parse_destinations

__all__ = ["Site", "site_from_world", "load_site_file", "load_site"]

_SITE_KEYS = ("name", "map", "dock", "destinations")


@dataclass(frozen=True)
class Site:
    """Named places, and optionally the map (with its never-moving obstacles) and the dock pose."""

    name: str
    destinations: dict[str, Destination] = field(default_factory=dict)
    map: OccupancyMap | None = None
    blocked: np.ndarray | None = None  # map cells a goal must keep clear of (occupied, unknown, static obstacles)
    dock: Pose | None = None
    source: str = ""


def site_from_world(world: World) -> Site:
    """The simulator world as a site: its destinations, its map plus static obstacles, its dock."""
    return Site(
        name=world.name,
        destinations=dict(world.destinations),
        map=world.map,
        blocked=world.static_obstacle_mask(),
        dock=world.dock,
        source=f"world {world.name}",
    )


def load_site_file(path: str | Path) -> Site:
    """A destinations file (see the module docstring), validated with file and key in every error."""
    source = Path(path).expanduser()
    raw = load_yaml(source)
    check_keys(raw, _SITE_KEYS, source, required=("destinations",))
    grid = None
    if "map" in raw:
        grid = load_map(as_file(raw["map"], source, "map", "map file"))
    dock = as_pose2d(raw["dock"], source, "dock") if "dock" in raw else None
    return Site(
        name=as_str(raw["name"], source, "name") if "name" in raw else source.stem,
        destinations=parse_destinations(raw["destinations"], source, grid),
        map=grid,
        blocked=grid.occupied_mask().copy() if grid is not None else None,
        dock=dock,
        source=str(source),
    )


def load_site(destinations_file: str = "", world: str = "") -> Site:
    """The destinations file if one is named, else the simulator world `world`."""
    if destinations_file.strip():
        return load_site_file(destinations_file.strip())
    if not world.strip():
        raise ConfigError(None, "destinations_file", "name a destinations file or a simulator world")
    return site_from_world(load_world(world.strip()))
