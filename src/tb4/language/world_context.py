"""What a program may refer to at a site: named destinations, and where the robot may be sent.

Destinations come from a Site (tb4.language.site: a destinations file, or a simulator world), so the model's
context, the offline interpreter and the executor's checks all agree. A goal is accepted only if it is finite and,
when the site has a map, on the map, in known free space, outside static obstacles and with room for the robot
around it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tb4.core.robot_params import robot_radius
from tb4.language.site import Site, site_from_world
from tb4.sim.world import Destination, World

__all__ = ["ROBOT_CLEARANCE", "DOCK_DESTINATION", "destination_table", "dock_approach", "pose_checker"]

#: Free space needed around a goal (m): the robot's footprint radius (robot.yaml), rounded up to the centimetre.
ROBOT_CLEARANCE = math.ceil(robot_radius() * 100.0) / 100.0
#: Name of the extra destination in front of the dock: the Create 3 docks only when it sees the station.
DOCK_DESTINATION = "dock"
_APPROACH_DISTANCES = (1.0, 0.8, 1.2, 0.6)


def _as_site(place: Site | World) -> Site:
    return place if isinstance(place, Site) else site_from_world(place)


def destination_table(place: Site | World) -> dict[str, list[float]]:
    """Destinations as the program sees them: name -> [x, y, heading in degrees], plus 'dock' (the approach pose)."""
    site = _as_site(place)
    table = {name: _row(dest) for name, dest in site.destinations.items()}
    if DOCK_DESTINATION not in table:
        approach = dock_approach(site)
        if approach is not None:
            table[DOCK_DESTINATION] = approach
    return table


def dock_approach(place: Site | World) -> list[float] | None:
    """[x, y, degrees] about 1 m behind the docked pose, facing the station, in free space (None if none is)."""
    site = _as_site(place)
    if site.dock is None:
        return None
    x, y, yaw = site.dock
    check = pose_checker(site)
    for distance in _APPROACH_DISTANCES:
        ax, ay = x - distance * math.cos(yaw), y - distance * math.sin(yaw)
        if check(ax, ay) is None:
            deg = math.degrees(yaw) % 360.0
            return [round(ax, 3), round(ay, 3), round(deg, 3)]
    return None


def _row(dest: Destination) -> list[float]:
    deg = math.degrees(dest.yaw)
    return [float(dest.x), float(dest.y), float(round(deg, 6)) if abs(deg - round(deg)) > 1e-9 else float(round(deg))]


def pose_checker(place: Site | World, clearance: float = ROBOT_CLEARANCE) -> Callable[[float, float], str | None]:
    """A check(x, y) -> problem text (None when the robot may be sent there). Without a map: finiteness only."""
    site = _as_site(place)
    grid, blocked = site.map, site.blocked  # blocked: occupied or unknown map cells + static extra obstacles
    if grid is None or blocked is None:
        return _finite_only
    reach = max(int(math.ceil(clearance / grid.resolution)), 0)

    def check(x: float, y: float) -> str | None:
        if not (math.isfinite(x) and math.isfinite(y)):
            return "coordinates are not finite"
        if not grid.in_bounds(x, y):
            lo_x, lo_y, hi_x, hi_y = grid.bounds
            return f"outside the map (x {lo_x:.1f}..{hi_x:.1f}, y {lo_y:.1f}..{hi_y:.1f})"
        value = grid.value_at(x, y)
        if value < 0:
            return "in unknown space on the map"
        row, col = grid.world_to_cell(x, y)
        r0, r1 = max(row - reach, 0), min(row + reach + 1, grid.height)
        c0, c1 = max(col - reach, 0), min(col + reach + 1, grid.width)
        window = blocked[r0:r1, c0:c1]
        rows, cols = np.mgrid[r0:r1, c0:c1]
        near = (rows - row) ** 2 + (cols - col) ** 2 <= reach * reach
        if bool(blocked[row, col]):
            return "inside a wall or obstacle"
        if bool(np.any(window & near)):
            return f"too close to a wall or obstacle (the robot needs {clearance:g} m around it)"
        return None

    return check


def _finite_only(x: float, y: float) -> str | None:
    return None if math.isfinite(x) and math.isfinite(y) else "coordinates are not finite"
