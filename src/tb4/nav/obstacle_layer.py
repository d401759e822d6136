"""The global costmap's obstacle layer (Nav2 ObstacleLayer on the map-sized grid, as the TurtleBot 4 runs it).

Semantics: each scan first clears (raytraces free space) every cell a beam crossed, from the sensor up to the hit
or to raytrace_max_range (a beam that saw nothing clears its whole reach), then marks the hit cells of beams
no longer than obstacle_max_range. Marks persist until a later beam passes through them or the costmap is
cleared (ClearEntireCostmap, ClearCostmapAroundRobot / ExceptRegion). Static walls are the static layer's: a
beam ending on a wall leaves the static cost as it was.

The result is the global costmap: (static | obstacles) inflated. Only the region a scan can change (the sensor's
raytrace reach plus the inflation radius) is re-inflated, so a scan costs the same in a 50 m warehouse as in a
small room.

The per-scan work (raytrace clearing, marking, re-inflation) runs in the C kernel tb4.nav._costmapkernel, the
former NumPy code operation for operation (tests/core/nav/obstacle_reference.py keeps that code; the tests
compare the two cell for cell). Re-inflation stamps inflation_table around LETHAL cells, which gives inflate()'s
distance-transform costs exactly when stamping_is_exact holds for the parameters (it does for every setting
tried); otherwise the region is re-inflated with inflate() as before.
"""

from __future__ import annotations

import math

import numpy as np

from tb4.core.kernels import load_kernel
from tb4.nav.costmap import LETHAL, Costmap2D, CostmapParams, inflate, inflation_table, stamping_is_exact

__all__ = ["GlobalObstacleLayer"]


class GlobalObstacleLayer:
    """Marks and clears lidar obstacles on the grid of the global costmap's static layer."""

    def __init__(self, static: Costmap2D, inflated: np.ndarray, params: CostmapParams) -> None:
        self.params = params
        self.static = static
        self._static_inflated = inflated
        self.marks = np.zeros(static.data.shape, dtype=bool)
        self._kernel = load_kernel("tb4.nav._costmapkernel")
        self._table, self._table_k = inflation_table(static.resolution, params)
        self._stamp = stamping_is_exact(self._table, self._table_k)
        self.costmap = Costmap2D(inflated.copy(), static.resolution, static.origin_x, static.origin_y, layer="global")

    def update(self, sx: float, sy: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
        """One scan from sensor (sx, sy): `hits` are beam end points, `free_ends` the reach of empty beams."""
        if not (math.isfinite(sx) and math.isfinite(sy)):
            raise ValueError("GlobalObstacleLayer.update: the sensor position must be finite")
        hits = _finite(hits)
        free_ends = _finite(free_ends)
        self.clear_rays(sx, sy, hits, free_ends)
        self.mark_hits(sx, sy, hits)
        p = self.params
        s = self.static
        res = s.resolution
        reach_cells = int(math.ceil(max(p.raytrace_max_range, p.obstacle_max_range) / res)) + 1
        # the sensor's cell as NumPy casts it (a sensor far off the map gives a cell off it, never an error)
        r0 = int(np.floor(np.float64((sy - s.origin_y) / res)).astype(np.int64))
        c0 = int(np.floor(np.float64((sx - s.origin_x) / res)).astype(np.int64))
        self._recompose(r0 - reach_cells, r0 + reach_cells, c0 - reach_cells, c0 + reach_cells)

    def _grid(self) -> tuple[np.ndarray, int, int, float, float, float]:
        s = self.static
        return self.marks, s.rows, s.cols, s.origin_x, s.origin_y, s.resolution

    def clear_rays(self, sx: float, sy: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
        """Clear the marks along every ray, sampled every half cell up to raytrace_max_range; a hit's ray (not
        clipped) stops half a cell short, so the hit's own cell is not cleared. Points: C-contiguous (N, 2)."""
        rmax = self.params.raytrace_max_range
        if len(hits):
            self._kernel.raytrace_clear(*self._grid(), hits, sx, sy, rmax, rmax, 2)
        if len(free_ends):
            self._kernel.raytrace_clear(*self._grid(), free_ends, sx, sy, rmax, rmax, 0)

    def mark_hits(self, sx: float, sy: float, hits: np.ndarray) -> None:
        """Mark the cells of the hits no farther than obstacle_max_range from the sensor."""
        if len(hits):
            self._kernel.mark(*self._grid(), hits, sx, sy, self.params.obstacle_max_range)

    def _recompose(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> None:
        """Re-inflate static | marks over rows/cols [lo, hi] (clipped), with a margin so edges inflate right."""
        s = self.static
        m = self.params.inflation_cells + 1
        rl, rh = max(r_lo - m, 0), min(r_hi + m + 1, s.rows)
        cl, ch = max(c_lo - m, 0), min(c_hi + m + 1, s.cols)
        if rl >= rh or cl >= ch:
            return
        ir, irh = max(r_lo, 0) - rl, min(r_hi + 1, s.rows) - rl
        ic, ich = max(c_lo, 0) - cl, min(c_hi + 1, s.cols) - cl
        if ir >= irh or ic >= ich:
            return
        if self._stamp:
            new = np.empty((irh - ir, ich - ic), dtype=np.uint8)
            self._kernel.reinflate(
                new, s.data, self.marks, s.rows, s.cols, rl, rh, cl, ch,
                rl + ir, rl + irh, cl + ic, cl + ich, self._table, self._table_k,
            )  # fmt: skip
        else:
            sub = s.data[rl:rh, cl:ch].copy()
            sub[self.marks[rl:rh, cl:ch]] = LETHAL
            new = inflate(sub, s.resolution, self.params)[ir:irh, ic:ich]
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
    return np.ascontiguousarray(pts[np.isfinite(pts).all(axis=1)])
