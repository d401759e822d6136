"""Collision of the circular robot with the static map and with circular (moving) obstacles, without tunnelling.

The static world is a Euclidean distance field: for every cell, the distance in metres from its centre to the
nearest occupied cell centre (scipy's exact EDT). Off-map space counts as occupied: the field is built on the
mask padded with an occupied border. The clearance of a point (distance to the nearest obstacle surface) is the
bilinear interpolation of the field minus half a cell, exact for axis-aligned walls and within a cell elsewhere.

Motion is checked by conservative advancement: the robot may move as far as its clearance minus its radius
without any check; beyond that it sub-steps (never less than `collision_min_step` cells), so however large
the step, it can never jump over a wall. On contact it stops at the last free pose.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from tb4.core.distance import distance_to_marked
from tb4.core.geometry import arc_pose
from tb4.core.maps import OccupancyMap

__all__ = [
    "Circles",
    "DistanceField",
    "circles_clearance",
    "CollisionChecker",
]

Circles = Sequence[tuple[float, float, float]]  # (x, y, radius) of circular obstacles at the current time


class DistanceField:
    """Distance (m) from each cell centre to the nearest occupied cell centre, on a grid padded with occupied cells.

    `dist` is indexed [row, col] like OccupancyMap.data but includes `pad` extra cells on every side;
    `origin_x/origin_y` are those of the padded grid.
    """

    def __init__(self, mask: np.ndarray, resolution: float, origin_x: float, origin_y: float, pad: int = 2) -> None:
        mask = np.asarray(mask, dtype=bool)
        if mask.ndim != 2:
            raise ValueError("occupancy mask must be 2D")
        padded = np.pad(mask, pad, mode="constant", constant_values=True)
        self.dist = distance_to_marked(padded, resolution)
        self.resolution = float(resolution)
        self.pad = pad
        self.origin_x = origin_x - pad * resolution
        self.origin_y = origin_y - pad * resolution
        self.height, self.width = self.dist.shape
        self._flat = self.dist.ravel()

    @classmethod
    def from_mask(cls, grid: OccupancyMap, mask: np.ndarray | None = None) -> DistanceField:
        """Field of `mask` (default: the grid's occupied/unknown cells) laid out like `grid`."""
        mask = grid.occupied_mask() if mask is None else mask
        if mask.shape != grid.data.shape:
            raise ValueError(f"mask shape {mask.shape} does not match the map {grid.data.shape}")
        return cls(mask, grid.resolution, grid.origin_x, grid.origin_y)

    def clearance(self, x: float, y: float) -> float:
        """Distance (m) from point (x, y) to the nearest occupied surface; negative inside or off the grid."""
        res = self.resolution
        fx = (x - self.origin_x) / res - 0.5
        fy = (y - self.origin_y) / res - 0.5
        if not (0.0 <= fx < self.width - 1 and 0.0 <= fy < self.height - 1):
            return -res
        c0, r0 = int(fx), int(fy)
        tx, ty = fx - c0, fy - r0
        i = r0 * self.width + c0
        f = self._flat
        d00, d01 = f.item(i), f.item(i + 1)
        d10, d11 = f.item(i + self.width), f.item(i + self.width + 1)
        d = (d00 * (1 - tx) + d01 * tx) * (1 - ty) + (d10 * (1 - tx) + d11 * tx) * ty
        return d - 0.5 * res


def circles_clearance(x: float, y: float, circles: Circles) -> float:
    """Distance from (x, y) to the nearest circle surface (inf when there are none)."""
    best = math.inf
    for cx, cy, r in circles:
        d = math.hypot(x - cx, y - cy) - r
        if d < best:
            best = d
    return best


class CollisionChecker:
    """Moves the circular robot along its arc, stopping at the last free pose on contact.

    Keeps a 'free budget' (static clearance minus radius, minus the distance driven since it was measured), so
    in open space a step costs no field lookup at all. Call reset() after teleports or map changes.
    """

    def __init__(self, field: DistanceField, radius: float, min_step_cells: float) -> None:
        self.field = field
        self.radius = radius
        self.min_step_cells = min_step_cells
        self.min_step = min_step_cells * field.resolution
        self._budget = -math.inf

    def reset(self, field: DistanceField | None = None) -> None:
        """Forget the free budget (after a teleport); with `field`, switch to a new map."""
        if field is not None:
            self.field = field
            self.min_step = self.min_step_cells * field.resolution
        self._budget = -math.inf

    def clearance(self, x: float, y: float, circles: Circles = ()) -> float:
        """Distance from (x, y) to the nearest obstacle surface (static or circle)."""
        return min(self.field.clearance(x, y), circles_clearance(x, y, circles))

    def in_contact(self, x: float, y: float, circles: Circles = ()) -> bool:
        return self.clearance(x, y, circles) < self.radius

    def touching(self, x: float, y: float, circles: Circles = ()) -> bool:
        """Within one minimum sub-step of contact (the bumper stays pressed while the robot creeps on it)."""
        reach = self.radius + self.min_step
        if self._budget > self.min_step and (not circles or circles_clearance(x, y, circles) > reach):
            return False
        return self.clearance(x, y, circles) < reach

    def move(
        self, x: float, y: float, yaw: float, v: float, w: float, dt: float, circles: Circles = ()
    ) -> tuple[float, float, float, bool]:
        """(x, y, yaw, blocked) after driving dt seconds at (v, w) from (x, y, yaw)."""
        length = abs(v) * dt
        if length <= 0.0:
            nx, ny, nyaw = arc_pose(x, y, yaw, 0.0, w, dt)
            return (x, y, nyaw, False)  # turning in place never collides: the footprint is a circle
        r = self.radius - 1e-9  # a step that lands exactly on the contact distance is free
        field = self.field
        done = 0.0
        cap = math.inf  # after a contact on a long sub-step, retry shorter ones down to min_step
        cx, cy, cyaw = x, y, yaw
        while True:
            remaining = length - done
            free = self._budget
            if circles:
                free = min(free, circles_clearance(cx, cy, circles) - r)
            if free >= remaining and cap >= remaining:
                self._budget -= remaining
                nx, ny, nyaw = arc_pose(x, y, yaw, v, w, dt)
                return (nx, ny, nyaw, False)
            ds = min(max(free, self.min_step), remaining, cap)
            nx, ny, nyaw = arc_pose(x, y, yaw, v, w, dt * (done + ds) / length)
            cs = field.clearance(nx, ny)
            c_new = min(cs, circles_clearance(nx, ny, circles)) if circles else cs
            if c_new < r and c_new <= self.clearance(cx, cy, circles):
                if ds > self.min_step * 1.001:
                    cap = max(0.5 * ds, self.min_step)
                    continue
                self._budget = -math.inf
                return (cx, cy, cyaw, True)  # contact (moving away from an overlap is allowed, see above)
            cx, cy, cyaw = nx, ny, nyaw
            done += ds
            cap = math.inf
            self._budget = cs - r
            if done >= length:
                return (cx, cy, cyaw, False)
