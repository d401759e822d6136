"""The global costmap's obstacle layer (Nav2 ObstacleLayer on the map-sized grid, as the TurtleBot 4 runs it).

Semantics: each scan first clears (raytraces free space) every cell a beam crossed, from the sensor up to the hit
or to raytrace_max_range (a beam that saw nothing clears its whole reach), then marks the hit cells of beams
no longer than obstacle_max_range. Marks persist until a later beam passes through them or the costmap is
cleared (ClearEntireCostmap, ClearCostmapAroundRobot / ExceptRegion). Static walls are the static layer's: a
beam ending on a wall leaves the static cost as it was.

The result is the global costmap: (static | obstacles) inflated. Only the region a scan can change (the sensor's
raytrace reach plus the inflation radius) is re-inflated, so a scan costs the same in a 50 m warehouse as in a
small room.
"""

from __future__ import annotations

import math

import numpy as np

from tb4.nav.costmap import LETHAL, Costmap2D, CostmapParams, inflate

__all__ = ["GlobalObstacleLayer"]


class GlobalObstacleLayer:
    """Marks and clears lidar obstacles on the grid of the global costmap's static layer."""

    def __init__(self, static: Costmap2D, inflated: np.ndarray, params: CostmapParams) -> None:
        self.params = params
        self.static = static
        self._static_inflated = inflated
        self.marks = np.zeros(static.data.shape, dtype=bool)
        self.costmap = Costmap2D(inflated.copy(), static.resolution, static.origin_x, static.origin_y, layer="global")

    def _cells(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = self.static
        rows = np.floor((pts[:, 1] - s.origin_y) / s.resolution).astype(np.int64)
        cols = np.floor((pts[:, 0] - s.origin_x) / s.resolution).astype(np.int64)
        inside = (rows >= 0) & (rows < s.rows) & (cols >= 0) & (cols < s.cols)
        return rows, cols, inside

    def update(self, sx: float, sy: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
        """One scan from sensor (sx, sy): `hits` are beam end points, `free_ends` the reach of empty beams."""
        if not (math.isfinite(sx) and math.isfinite(sy)):
            raise ValueError("GlobalObstacleLayer.update: the sensor position must be finite")
        hits = _finite(hits)
        free_ends = _finite(free_ends)
        p = self.params
        res = self.static.resolution
        ends = np.concatenate([hits, free_ends]) if len(free_ends) else hits
        if len(ends):
            vec = ends - (sx, sy)
            length = np.hypot(vec[:, 0], vec[:, 1])
            ok = length > 1e-9
            is_hit = np.concatenate([np.ones(len(hits), bool), np.zeros(len(free_ends), bool)])[ok]
            vec, length = vec[ok], length[ok]
            reach = np.minimum(length, p.raytrace_max_range)
            # a hit's own cell is not cleared; stop half a cell short of it
            reach = np.where(is_hit & (length <= p.raytrace_max_range), np.maximum(reach - 0.5 * res, 0.0), reach)
            step = 0.5 * res
            n = int(math.ceil(float(reach.max(initial=0.0)) / step)) + 1
            t = np.arange(n) * step
            unit = vec / length[:, None]
            valid = t[None, :] < reach[:, None]
            pts = np.stack([(sx + unit[:, 0:1] * t)[valid], (sy + unit[:, 1:2] * t)[valid]], axis=1)
            rows, cols, inside = self._cells(pts)
            self.marks[rows[inside], cols[inside]] = False
        if len(hits):
            near = hits[np.hypot(hits[:, 0] - sx, hits[:, 1] - sy) <= p.obstacle_max_range]
            rows, cols, inside = self._cells(near)
            self.marks[rows[inside], cols[inside]] = True
        reach_cells = int(math.ceil(max(p.raytrace_max_range, p.obstacle_max_range) / res)) + 1
        r0, c0, _ = self._cells(np.array([[sx, sy]]))
        self._recompose(
            int(r0[0]) - reach_cells, int(r0[0]) + reach_cells, int(c0[0]) - reach_cells, int(c0[0]) + reach_cells
        )

    def _recompose(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> None:
        """Re-inflate static | marks over rows/cols [lo, hi] (clipped), with a margin so edges inflate right."""
        s = self.static
        m = self.params.inflation_cells + 1
        rl, rh = max(r_lo - m, 0), min(r_hi + m + 1, s.rows)
        cl, ch = max(c_lo - m, 0), min(c_hi + m + 1, s.cols)
        if rl >= rh or cl >= ch:
            return
        sub = s.data[rl:rh, cl:ch].copy()
        sub[self.marks[rl:rh, cl:ch]] = LETHAL
        inflated = inflate(sub, s.resolution, self.params)
        ir, irh = max(r_lo, 0) - rl, min(r_hi + 1, s.rows) - rl
        ic, ich = max(c_lo, 0) - cl, min(c_hi + 1, s.cols) - cl
        if ir >= irh or ic >= ich:
            return
        new = inflated[ir:irh, ic:ich]
        box = (slice(rl + ir, rl + irh), slice(cl + ic, cl + ich))
        if np.array_equal(self.costmap.data[box], new):
            return
        data = self.costmap.data.copy()  # a new costmap object: readers holding the old one see a consistent map
        data[box] = new
        self.costmap = Costmap2D(data, s.resolution, s.origin_x, s.origin_y, layer="global")

    def clear(self) -> None:
        """ClearEntireCostmap: no marks; static + inflation."""
        self.marks[:] = False
        self.costmap = Costmap2D(
            self._static_inflated.copy(),
            self.static.resolution,
            self.static.origin_x,
            self.static.origin_y,
            layer="global",
        )

    def _clear_mask(self, mask: np.ndarray) -> None:
        rows, cols = np.nonzero(mask & self.marks)
        if len(rows) == 0:
            return
        self.marks[mask] = False
        self._recompose(int(rows.min()), int(rows.max()), int(cols.min()), int(cols.max()))

    def _square(self, x: float, y: float, reset_distance: float) -> np.ndarray:
        s = self.static
        cx = s.origin_x + (np.arange(s.cols) + 0.5) * s.resolution
        cy = s.origin_y + (np.arange(s.rows) + 0.5) * s.resolution
        half = reset_distance / 2.0
        return (np.abs(cy - y)[:, None] <= half) & (np.abs(cx - x)[None, :] <= half)

    def clear_around(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapAroundRobot on the global costmap."""
        self._clear_mask(self._square(x, y, reset_distance))

    def clear_except_region(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapExceptRegion on the global costmap."""
        self._clear_mask(~self._square(x, y, reset_distance))


def _finite(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return pts[np.isfinite(pts).all(axis=1)]
