"""The NumPy reference of the global obstacle layer's kernel work (tb4.nav._costmapkernel): raytrace clearing,
marking and re-inflation exactly as tb4.nav.obstacle_layer did them before the kernel, kept here so the tests can
compare the two cell for cell. Not used at run time."""

from __future__ import annotations

import math

import numpy as np

from tb4.nav.costmap import LETHAL, Costmap2D, inflate
from tb4.nav.obstacle_layer import GlobalObstacleLayer

__all__ = ["ReferenceGlobalObstacleLayer"]


class ReferenceGlobalObstacleLayer(GlobalObstacleLayer):
    """GlobalObstacleLayer with the former NumPy update and re-inflation (a scipy distance transform)."""

    def _cells(self, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        s = self.static
        rows = np.floor((pts[:, 1] - s.origin_y) / s.resolution).astype(np.int64)
        cols = np.floor((pts[:, 0] - s.origin_x) / s.resolution).astype(np.int64)
        inside = (rows >= 0) & (rows < s.rows) & (cols >= 0) & (cols < s.cols)
        return rows, cols, inside

    def update(self, sx: float, sy: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
        if not (math.isfinite(sx) and math.isfinite(sy)):
            raise ValueError("GlobalObstacleLayer.update: the sensor position must be finite")
        hits = _finite(hits)
        free_ends = _finite(free_ends)
        self.clear_rays(sx, sy, hits, free_ends)
        self.mark_hits(sx, sy, hits)
        p = self.params
        res = self.static.resolution
        reach_cells = int(math.ceil(max(p.raytrace_max_range, p.obstacle_max_range) / res)) + 1
        r0, c0, _ = self._cells(np.array([[sx, sy]]))
        self._recompose(
            int(r0[0]) - reach_cells, int(r0[0]) + reach_cells, int(c0[0]) - reach_cells, int(c0[0]) + reach_cells
        )

    def clear_rays(self, sx: float, sy: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
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

    def mark_hits(self, sx: float, sy: float, hits: np.ndarray) -> None:
        if len(hits):
            near = hits[np.hypot(hits[:, 0] - sx, hits[:, 1] - sy) <= self.params.obstacle_max_range]
            rows, cols, inside = self._cells(near)
            self.marks[rows[inside], cols[inside]] = True

    def _recompose(self, r_lo: int, r_hi: int, c_lo: int, c_hi: int) -> None:
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
        data = self.costmap.data.copy()
        data[box] = new
        self.costmap = Costmap2D(data, s.resolution, s.origin_x, s.origin_y, layer="global")


def _finite(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return pts[np.isfinite(pts).all(axis=1)]
