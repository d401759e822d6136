"""Obstacles that are not in the map: their shape, their motion as a pure function of sim time, and the one
rasterization of them onto a map grid (the world's static mask, the collision model's distance field)."""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from tb4.core.maps import OccupancyMap

__all__ = ["Obstacle", "PathMover", "rasterize_obstacles", "static_mask"]


@dataclass(frozen=True)
class Obstacle:
    """An obstacle that is not in the map. A one-point path is static; a longer one is followed at `speed`."""

    shape: str
    radius: float = 0.0
    size: tuple[float, float] = (0.0, 0.0)
    yaw: float = 0.0
    path: tuple[tuple[float, float], ...] = ()
    speed: float = 0.0
    mode: str = "pingpong"

    @property
    def moving(self) -> bool:
        return len(self.path) > 1 and self.speed > 0.0

    def track(self) -> np.ndarray:
        """The (N, 2) polyline the obstacle follows; closed (first point repeated) in loop mode."""
        pts = np.asarray(self.path, dtype=np.float64).reshape(-1, 2)
        if self.mode == "loop" and len(pts) > 1:
            pts = np.vstack([pts, pts[:1]])
        return pts

    def position_at(self, t: float) -> tuple[float, float]:
        """Centre at sim time `t`: a pure function of time, so every run (and every replay) sees the same motion.

        pingpong runs along the polyline and back; loop runs around the closed polyline. Both start at path[0].
        """
        if not self.path:
            return (0.0, 0.0)
        if not self.moving:
            return (float(self.path[0][0]), float(self.path[0][1]))
        pts = self.track()
        seg = np.hypot(*np.diff(pts, axis=0).T)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        length = float(cum[-1])
        if length <= 0.0:
            return (float(pts[0, 0]), float(pts[0, 1]))
        travelled = self.speed * float(t)
        if self.mode == "loop":
            s = travelled % length
        else:
            s = travelled % (2.0 * length)
            if s > length:
                s = 2.0 * length - s
        i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1))
        frac = 0.0 if seg[i] <= 0.0 else (s - cum[i]) / seg[i]
        p = pts[i] + frac * (pts[i + 1] - pts[i])
        return (float(p[0]), float(p[1]))

    def contains(self, x: np.ndarray | float, y: np.ndarray | float, t: float = 0.0, margin: float = 0.0) -> np.ndarray:
        """Whether points lie inside the obstacle (grown by `margin`) at time `t`. Vectorized over x, y."""
        cx, cy = self.position_at(t)
        dx = np.asarray(x, dtype=np.float64) - cx
        dy = np.asarray(y, dtype=np.float64) - cy
        if self.shape == "circle":
            return np.asarray(dx * dx + dy * dy <= (self.radius + margin) ** 2)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        along = dx * c + dy * s
        across = -dx * s + dy * c
        return np.asarray((np.abs(along) <= self.size[0] / 2 + margin) & (np.abs(across) <= self.size[1] / 2 + margin))

    def extent(self) -> float:
        """Radius of a circle around the centre that holds the whole obstacle."""
        if self.shape == "circle":
            return self.radius
        return 0.5 * math.hypot(self.size[0], self.size[1])


def rasterize_obstacles(
    grid: OccupancyMap, obstacles: Iterable[Obstacle], t: float = 0.0, mask: np.ndarray | None = None
) -> np.ndarray:
    """Mark the cells whose centres lie inside any obstacle (at time `t`) in a bool grid shaped like `grid.data`.

    Only the bounding window of each obstacle is evaluated, so this costs a few hundred cells per obstacle.
    """
    out = np.zeros(grid.data.shape, dtype=bool) if mask is None else mask
    res = grid.resolution
    for obs in obstacles:
        cx, cy = obs.position_at(t)
        r = obs.extent()
        c0 = max(int(math.floor((cx - r - grid.origin_x) / res)), 0)
        c1 = min(int(math.ceil((cx + r - grid.origin_x) / res)) + 1, grid.width)
        r0 = max(int(math.floor((cy - r - grid.origin_y) / res)), 0)
        r1 = min(int(math.ceil((cy + r - grid.origin_y) / res)) + 1, grid.height)
        if c0 >= c1 or r0 >= r1:
            continue
        xs = grid.origin_x + (np.arange(c0, c1) + 0.5) * res
        ys = grid.origin_y + (np.arange(r0, r1) + 0.5) * res
        inside = obs.contains(xs[None, :], ys[:, None], t)
        out[r0:r1, c0:c1] |= inside
    return out


def static_mask(grid: OccupancyMap, obstacles: Iterable[Obstacle] = ()) -> np.ndarray:
    """Cells that never move: the grid's occupied or unknown cells plus the obstacles that stand still."""
    return rasterize_obstacles(grid, [o for o in obstacles if not o.moving], mask=grid.occupied_mask().copy())


class PathMover:
    """Position of a moving obstacle along its path, in plain Python (Obstacle.position_at uses NumPy and costs
    ~30 us a call, too much 100 times per sim second). Same pingpong/loop semantics; checked against
    position_at in the tests. Objects without a path fall back to their own position_at."""

    def __init__(self, obstacle: Obstacle) -> None:
        self.obstacle = obstacle
        path = [(float(px), float(py)) for px, py in getattr(obstacle, "path", ())]
        self.speed = float(getattr(obstacle, "speed", 0.0))
        self.loop = getattr(obstacle, "mode", "pingpong") == "loop"
        if self.loop and len(path) > 1:
            path.append(path[0])
        self.pts = path
        self.cum = [0.0]
        for (ax, ay), (bx, by) in zip(path, path[1:], strict=False):
            self.cum.append(self.cum[-1] + math.hypot(bx - ax, by - ay))
        self.fast = len(path) > 1 and self.cum[-1] > 0.0

    def position(self, t: float) -> tuple[float, float]:
        if not self.fast:
            px, py = self.obstacle.position_at(t)
            return (float(px), float(py))
        length = self.cum[-1]
        s = self.speed * t
        if self.loop:
            s %= length
        else:
            s %= 2.0 * length
            if s > length:
                s = 2.0 * length - s
        i = min(max(bisect.bisect_right(self.cum, s) - 1, 0), len(self.pts) - 2)
        seg = self.cum[i + 1] - self.cum[i]
        frac = 0.0 if seg <= 0.0 else (s - self.cum[i]) / seg
        (ax, ay), (bx, by) = self.pts[i], self.pts[i + 1]
        return (ax + frac * (bx - ax), ay + frac * (by - ay))
