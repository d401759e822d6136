"""The rolling local costmap: a window centred on the robot with lidar obstacles (marked LETHAL, cleared by
raytracing from the sensor), the static map's walls in the window, and Nav2's inflation (tb4.nav.costmap).

The per-scan work (clearing along every ray, marking the hits, composing and inflating the window) runs in the C
kernel tb4.nav._costmapkernel, the former NumPy code operation for operation (the same cells cleared and marked,
the same costs; tests/core/nav/costmap_reference.py keeps that NumPy code and the tests compare the two)."""

from __future__ import annotations

import copy
import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from tb4.core.kernels import load_kernel
from tb4.nav.costmap import (
    DEFAULT_RESOLUTION,
    Costmap2D,
    CostmapParams,
    GlobalCostmap,
    inflation_table,
)

__all__ = ["LocalCostmap"]


@dataclass
class _Window:
    """Integer cell coordinates of the rolling window's lower-left cell in the anchor grid."""

    row: int = 0
    col: int = 0
    anchor_x: float = 0.0
    anchor_y: float = 0.0
    resolution: float = DEFAULT_RESOLUTION
    shape: tuple[int, int] = field(default=(0, 0))

    @property
    def origin(self) -> tuple[float, float]:
        return (self.anchor_x + self.col * self.resolution, self.anchor_y + self.row * self.resolution)


class LocalCostmap:
    """Rolling-window local costmap centred on the robot: lidar obstacles (marked LETHAL, cleared by raytracing
    from the sensor) + the static map's walls in the window + inflation."""

    def __init__(self, params: CostmapParams | None = None, static: GlobalCostmap | None = None) -> None:
        self._kernel = load_kernel("tb4.nav._costmapkernel")
        self.params = params or CostmapParams()
        self._static = static
        res = self.params.resolution
        shape = (max(1, round(self.params.height / res)), max(1, round(self.params.width / res)))
        anchor = (static.static.origin_x, static.static.origin_y) if static is not None else (0.0, 0.0)
        self._win = _Window(anchor_x=anchor[0], anchor_y=anchor[1], resolution=res, shape=shape)
        self._obstacles = np.zeros(shape, dtype=bool)
        self._table, self._table_k = inflation_table(res, self.params)
        self.costmap: Costmap2D
        self._place_window(0.0, 0.0)
        self._compose()

    @property
    def obstacles(self) -> np.ndarray:
        """The obstacle layer (bool, window cells), read-only view for inspection and tests."""
        view = self._obstacles.view()
        view.flags.writeable = False
        return view

    def copy(self) -> LocalCostmap:
        """An independent copy: updating it leaves this costmap as it is (a reader's fresh view)."""
        other = copy.copy(self)
        other._win = dataclasses.replace(self._win)
        other._obstacles = self._obstacles.copy()
        return other

    def set_static(self, static: GlobalCostmap | None) -> None:
        """Follow a map change (the window re-anchors to the new map's grid on the next update)."""
        self._static = static
        if static is not None:
            self._win.anchor_x, self._win.anchor_y = static.static.origin_x, static.static.origin_y
        self._obstacles[:] = False
        self._compose()

    # --- window --------------------------------------------------------------------------------------
    def _place_window(self, robot_x: float, robot_y: float) -> None:
        """Re-anchor the window on cell boundaries so the robot is in its centre cell; keep overlapping marks."""
        win = self._win
        res = win.resolution
        rows, cols = win.shape
        new_row = int(math.floor((robot_y - win.anchor_y) / res)) - rows // 2
        new_col = int(math.floor((robot_x - win.anchor_x) / res)) - cols // 2
        dr, dc = new_row - win.row, new_col - win.col
        if dr or dc:
            shifted = np.zeros_like(self._obstacles)
            src_r = slice(max(0, dr), min(rows, rows + dr))
            dst_r = slice(max(0, -dr), min(rows, rows - dr))
            src_c = slice(max(0, dc), min(cols, cols + dc))
            dst_c = slice(max(0, -dc), min(cols, cols - dc))
            if src_r.start < src_r.stop and src_c.start < src_c.stop:
                shifted[dst_r, dst_c] = self._obstacles[src_r, src_c]
            self._obstacles = shifted
        win.row, win.col = new_row, new_col

    def _marks_grid(self) -> tuple[np.ndarray, int, int, float, float, float]:
        """The obstacle layer as the kernel takes it: (grid, rows, cols, origin_x, origin_y, resolution)."""
        ox, oy = self._win.origin
        rows, cols = self._win.shape
        return self._obstacles, rows, cols, ox, oy, self._win.resolution

    # --- sensor update -------------------------------------------------------------------------------
    def update(
        self,
        robot_x: float,
        robot_y: float,
        scan_points: np.ndarray,
        sensor_x: float,
        sensor_y: float,
        free_endpoints: np.ndarray | None = None,
    ) -> None:
        """Move the window to the robot, clear along every ray, then mark the hits (map frame, metres)."""
        if not all(math.isfinite(v) for v in (robot_x, robot_y, sensor_x, sensor_y)):
            raise ValueError("LocalCostmap.update: robot and sensor positions must be finite")
        self._place_window(robot_x, robot_y)
        hits = _finite_points(scan_points)
        free = _finite_points(free_endpoints) if free_endpoints is not None else np.zeros((0, 2))
        self._raytrace_clear(hits, sensor_x, sensor_y, exclude_end=True)
        self._raytrace_clear(free, sensor_x, sensor_y, exclude_end=False)
        if len(hits):
            self._kernel.mark(*self._marks_grid(), hits, sensor_x, sensor_y, self.params.obstacle_max_range)
        self._compose()

    def _raytrace_clear(self, ends: np.ndarray, sx: float, sy: float, exclude_end: bool) -> None:
        """Clear obstacle cells along all rays sensor -> end (clipped to raytrace_max_range), sampled every half
        cell (every crossed cell is visited). Nothing beyond the window can be cleared, so each ray stops at the
        window's half-diagonal. With exclude_end the hit's own cell is not cleared (it is about to be marked), as
        in Nav2's raytraceFreespace, unless the ray was clipped."""
        if len(ends) == 0:
            return
        rows, cols = self._win.shape
        res = self._win.resolution
        half_diagonal = 0.5 * math.hypot(rows, cols) * res + res
        limit = min(self.params.raytrace_max_range, half_diagonal)
        mode = 1 if exclude_end else 0  # 1: a ray no longer than raytrace_max_range leaves its end cell
        self._kernel.raytrace_clear(*self._marks_grid(), ends, sx, sy, limit, self.params.raytrace_max_range, mode)

    # --- clearing services ---------------------------------------------------------------------------
    def clear(self) -> None:
        """ClearEntireCostmap: empty the obstacle layer."""
        self._obstacles[:] = False
        self._compose()

    def _square_mask(self, x: float, y: float, reset_distance: float) -> np.ndarray:
        ox, oy = self._win.origin
        res = self._win.resolution
        rows, cols = self._win.shape
        cx = ox + (np.arange(cols) + 0.5) * res
        cy = oy + (np.arange(rows) + 0.5) * res
        half = reset_distance / 2.0
        return (np.abs(cy - y)[:, None] <= half) & (np.abs(cx - x)[None, :] <= half)

    def clear_around(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapAroundRobot: clear obstacle cells inside the square of side reset_distance at (x, y)."""
        self._obstacles[self._square_mask(x, y, reset_distance)] = False
        self._compose()

    def clear_except_region(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapExceptRegion: clear obstacle cells outside the square of side reset_distance at (x, y)."""
        self._obstacles[~self._square_mask(x, y, reset_distance)] = False
        self._compose()

    # --- composition ---------------------------------------------------------------------------------
    def _compose(self) -> None:
        """The window's costmap: the static map's walls (sampled at the cell centres of the window grown by the
        inflation reach, so walls just outside still inflate in) and the obstacle marks, inflated."""
        rows, cols = self._win.shape
        ox, oy = self._win.origin
        res = self._win.resolution
        data = np.empty((rows, cols), dtype=np.uint8)
        static: tuple[np.ndarray | bytes, int, int, float, float, float] = (b"", 0, 0, 0.0, 0.0, 1.0)  # none
        if self._static is not None:
            s = self._static.static
            static = (s.data, s.rows, s.cols, s.origin_x, s.origin_y, s.resolution)
        margin = self.params.inflation_cells + 1
        self._kernel.compose(
            data, rows, cols, ox, oy, res, self._obstacles, *static, margin, self._table, self._table_k
        )
        self.costmap = Costmap2D(data, res, ox, oy, layer="local")


def _finite_points(points: np.ndarray | None) -> np.ndarray:
    if points is None:
        return np.zeros((0, 2))
    pts = np.asarray(points, dtype=np.float64)
    if pts.size == 0:
        return np.zeros((0, 2))
    pts = pts.reshape(-1, pts.shape[-1])[:, :2]
    return np.ascontiguousarray(pts[np.isfinite(pts).all(axis=1)])
