"""What a program may refer to in a world: named destinations, and where the robot may be sent.

Destinations come from the world file (name, pose, description, aliases) so the model's context, the offline
interpreter and the executor's checks all agree. A goal is accepted only if it is finite, on the map, in known free
space, outside static obstacles and with room for the robot around it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from tb4.sim.world import Destination, World

__all__ = ["ROBOT_CLEARANCE", "DOCK_DESTINATION", "destination_table", "dock_approach", "pose_checker"]

#: Free space needed around a goal (m): the TurtleBot 4 footprint radius.
ROBOT_CLEARANCE = 0.18
#: Name of the extra destination in front of the dock: the Create 3 docks only when it sees the station.
DOCK_DESTINATION = "dock"
_APPROACH_DISTANCES = (1.0, 0.8, 1.2, 0.6)


def destination_table(world: World) -> dict[str, list[float]]:
    """Destinations as the program sees them: name -> [x, y, heading in degrees], plus 'dock' (the approach pose)."""
    table = {name: _row(dest) for name, dest in world.destinations.items()}
    if DOCK_DESTINATION not in table:
        approach = dock_approach(world)
        if approach is not None:
            table[DOCK_DESTINATION] = approach
    return table


def dock_approach(world: World) -> list[float] | None:
    """[x, y, degrees] about 1 m behind the docked pose, facing the station, in free space (None if none is)."""
    x, y, yaw = world.dock
    check = pose_checker(world)
    for distance in _APPROACH_DISTANCES:
        ax, ay = x - distance * math.cos(yaw), y - distance * math.sin(yaw)
        if check(ax, ay) is None:
            deg = math.degrees(yaw) % 360.0
            return [round(ax, 3), round(ay, 3), round(deg, 3)]
    return None


def _row(dest: Destination) -> list[float]:
    deg = math.degrees(dest.yaw)
    return [float(dest.x), float(dest.y), float(round(deg, 6)) if abs(deg - round(deg)) > 1e-9 else float(round(deg))]


def pose_checker(world: World, clearance: float = ROBOT_CLEARANCE) -> Callable[[float, float], str | None]:
    """A check(x, y) -> problem text (None when the robot may be sent there)."""
    grid = world.map
    blocked = world.static_obstacle_mask()  # occupied or unknown map cells + static extra obstacles
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
