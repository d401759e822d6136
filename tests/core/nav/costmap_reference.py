"""The NumPy reference of the costmap kernel (tb4.nav._costmapkernel): the local costmap's raytrace clearing,
marking and composition exactly as tb4.nav.local_costmap did them before the kernel, kept here so the tests can
compare the two cell for cell. Not used at run time."""

from __future__ import annotations

import math

import numpy as np

from tb4.nav.costmap import LETHAL, inflate
from tb4.nav.local_costmap import LocalCostmap, _finite_points

__all__ = ["ReferenceLocalCostmap"]


class ReferenceLocalCostmap(LocalCostmap):
    """LocalCostmap with the former NumPy update and composition."""

    def _window_cells(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ox, oy = self._win.origin
        res = self._win.resolution
        rows = np.floor((points[:, 1] - oy) / res).astype(np.int64)
        cols = np.floor((points[:, 0] - ox) / res).astype(np.int64)
        inside = (rows >= 0) & (rows < self._win.shape[0]) & (cols >= 0) & (cols < self._win.shape[1])
        return rows, cols, inside

    def update(
        self,
        robot_x: float,
        robot_y: float,
        scan_points: np.ndarray,
        sensor_x: float,
        sensor_y: float,
        free_endpoints: np.ndarray | None = None,
    ) -> None:
        if not all(math.isfinite(v) for v in (robot_x, robot_y, sensor_x, sensor_y)):
            raise ValueError("LocalCostmap.update: robot and sensor positions must be finite")
        self._place_window(robot_x, robot_y)
        hits = _finite_points(scan_points)
        free = _finite_points(free_endpoints) if free_endpoints is not None else np.zeros((0, 2))
        self._raytrace_clear(hits, sensor_x, sensor_y, exclude_end=True)
        self._raytrace_clear(free, sensor_x, sensor_y, exclude_end=False)
        if len(hits):
            self.mark(hits, sensor_x, sensor_y)
        self._compose()

    def mark(self, hits: np.ndarray, sensor_x: float, sensor_y: float) -> None:
        dist = np.hypot(hits[:, 0] - sensor_x, hits[:, 1] - sensor_y)
        near = hits[dist <= self.params.obstacle_max_range]
        rows, cols, inside = self._window_cells(near)
        self._obstacles[rows[inside], cols[inside]] = True

    def _raytrace_clear(self, ends: np.ndarray, sx: float, sy: float, exclude_end: bool) -> None:
        if len(ends) == 0:
            return
        vec = ends - np.array([sx, sy])
        length = np.hypot(vec[:, 0], vec[:, 1])
        ok = length > 1e-9
        vec, length, ends = vec[ok], length[ok], ends[ok]
        if len(ends) == 0:
            return
        rows_n, cols_n = self._win.shape
        half_diagonal = 0.5 * math.hypot(rows_n, cols_n) * self._win.resolution + self._win.resolution
        reach = np.minimum(length, min(self.params.raytrace_max_range, half_diagonal))
        step = self._win.resolution / 2.0
        n = int(math.ceil(float(reach.max()) / step)) + 1
        t = np.arange(n, dtype=np.float64) * step
        unit = vec / length[:, None]
        px = sx + unit[:, 0:1] * t[None, :]
        py = sy + unit[:, 1:2] * t[None, :]
        valid = t[None, :] < reach[:, None]
        pts = np.stack([px[valid], py[valid]], axis=1)
        rows, cols, inside = self._window_cells(pts)
        if exclude_end:
            er, ec, _ = self._window_cells(ends)
            ray_id = np.broadcast_to(np.arange(len(ends))[:, None], valid.shape)[valid]
            clipped = length[ray_id] > self.params.raytrace_max_range
            inside &= clipped | (rows != er[ray_id]) | (cols != ec[ray_id])
        self._obstacles[rows[inside], cols[inside]] = False

    def _static_lethal(self, margin: int) -> np.ndarray:
        rows, cols = self._win.shape
        out = np.zeros((rows + 2 * margin, cols + 2 * margin), dtype=bool)
        if self._static is None:
            return out
        ox, oy = self._win.origin
        res = self._win.resolution
        xs = ox + (np.arange(-margin, cols + margin) + 0.5) * res
        ys = oy + (np.arange(-margin, rows + margin) + 0.5) * res
        gx, gy = np.meshgrid(xs, ys)
        costs = self._static.static.costs_at(np.stack([gx.ravel(), gy.ravel()], axis=1))
        return (costs == LETHAL).reshape(out.shape)

    def _compose(self) -> None:
        from tb4.nav.costmap import Costmap2D

        margin = self.params.inflation_cells + 1
        rows, cols = self._win.shape
        big = np.zeros((rows + 2 * margin, cols + 2 * margin), dtype=np.uint8)
        big[self._static_lethal(margin)] = LETHAL
        inner = big[margin : margin + rows, margin : margin + cols]
        inner[self._obstacles] = LETHAL
        data = inflate(big, self._win.resolution, self.params)[margin : margin + rows, margin : margin + cols]
        ox, oy = self._win.origin
        self.costmap = Costmap2D(data, self._win.resolution, ox, oy, layer="local")
