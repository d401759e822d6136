"""Nav2-compatible costmaps: the cost grid type, Nav2's cost values and inflation, and the global costmap (static
map + inflation, with the optional lidar obstacle layer). The rolling local costmap is local_costmap.py.

Cost values and the inflation formula are Nav2's, so costmaps served over `get_costmap` read the same as on a
real robot and user code that thresholds on 253/254 keeps working. Everything is vectorized: inflation is one
Euclidean distance transform, raytracing samples every ray at once. The rolling local costmap, rebuilt every scan,
does the same in the C kernel tb4.nav._costmapkernel (inflation by stamping inflation_table around LETHAL cells).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tb4.config import ConfigError, as_bool, as_float, check_keys
from tb4.core import robot_params
from tb4.core.distance import distance_to_marked
from tb4.core.maps import OccupancyMap

__all__ = [
    "FREE_SPACE",
    "INSCRIBED",
    "LETHAL",
    "NO_INFORMATION",
    "MAX_NON_OBSTACLE",
    "OCCUPIED_THRESHOLD",
    "Costmap2D",
    "CostmapParams",
    "inflation_cost",
    "inflate",
    "inflation_table",
    "stamping_is_exact",
    "static_layer_from_map",
    "StaticLayers",
    "GlobalCostmap",
]

FREE_SPACE = 0
MAX_NON_OBSTACLE = 252
INSCRIBED = 253
LETHAL = 254
NO_INFORMATION = 255

# Map cells at or above this occupancy are walls. It matches OccupancyMap.occupied_mask (map_server's
# occupied_thresh 0.65), so the planner and the simulator's collision model agree on what is a wall.
OCCUPIED_THRESHOLD = 65

# Defaults for costmaps built without nav2.yaml (tests, tools): turtlebot4_navigation's values. The simulator's
# costmaps take theirs from src/tb4/params/nav2.yaml through Nav2Params.costmap_params; the robot radius always
# comes from robot.yaml (tb4.core.robot_params).
DEFAULT_RESOLUTION = 0.06
DEFAULT_INFLATION_RADIUS = 0.45
DEFAULT_COST_SCALING_FACTOR = 4.0
DEFAULT_LOCAL_WIDTH = 3.0
DEFAULT_LOCAL_HEIGHT = 3.0
DEFAULT_OBSTACLE_MAX_RANGE = 2.5
DEFAULT_RAYTRACE_MAX_RANGE = 3.0


@dataclass
class Costmap2D:
    """A uint8 cost grid, `data[row, col]` with row 0 at `origin_y` (bottom), like nav2_msgs/Costmap."""

    data: np.ndarray
    resolution: float
    origin_x: float
    origin_y: float
    layer: str = ""

    def __post_init__(self) -> None:
        self.data = np.ascontiguousarray(self.data, dtype=np.uint8)
        if self.data.ndim != 2:
            raise ValueError("costmap data must be a 2D array")
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"costmap resolution must be a positive number, got {self.resolution}")

    @property
    def rows(self) -> int:
        return int(self.data.shape[0])

    @property
    def cols(self) -> int:
        return int(self.data.shape[1])

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell holding (x, y); may be outside the grid."""
        return (
            int(math.floor((y - self.origin_y) / self.resolution)),
            int(math.floor((x - self.origin_x) / self.resolution)),
        )

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """Centre of cell (row, col)."""
        return (self.origin_x + (col + 0.5) * self.resolution, self.origin_y + (row + 0.5) * self.resolution)

    def in_bounds(self, x: float, y: float) -> bool:
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        row, col = self.world_to_cell(x, y)
        return 0 <= row < self.rows and 0 <= col < self.cols

    def cost_at(self, x: float, y: float) -> int:
        """Cost at (x, y); NO_INFORMATION off the map."""
        if not self.in_bounds(x, y):
            return NO_INFORMATION
        row, col = self.world_to_cell(x, y)
        return int(self.data[row, col])

    def cells_of(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Vectorized world_to_cell for (N, 2+) points: (rows, cols, inside) with inside False for off-map or
        non-finite points (their row/col are clipped to 0 so they can still index safely)."""
        pts = np.atleast_2d(np.asarray(points, dtype=np.float64))
        finite = np.isfinite(pts[:, 0]) & np.isfinite(pts[:, 1])
        xs = np.where(finite, pts[:, 0], self.origin_x)
        ys = np.where(finite, pts[:, 1], self.origin_y)
        rows = np.floor((ys - self.origin_y) / self.resolution).astype(np.int64)
        cols = np.floor((xs - self.origin_x) / self.resolution).astype(np.int64)
        inside = finite & (rows >= 0) & (rows < self.rows) & (cols >= 0) & (cols < self.cols)
        return np.where(inside, rows, 0), np.where(inside, cols, 0), inside

    def costs_at(self, points: np.ndarray) -> np.ndarray:
        """Vectorized cost_at for (N, 2+) points; NO_INFORMATION off the map."""
        rows, cols, inside = self.cells_of(points)
        return np.where(inside, self.data[rows, cols], NO_INFORMATION).astype(np.uint8)

    def copy(self) -> Costmap2D:
        return Costmap2D(self.data.copy(), self.resolution, self.origin_x, self.origin_y, self.layer)


@dataclass(frozen=True)
class CostmapParams:
    """Costmap parameters with the upstream Nav2 names and the TurtleBot 4 defaults."""

    resolution: float = DEFAULT_RESOLUTION
    robot_radius: float = field(default_factory=robot_params.robot_radius)
    inflation_radius: float = DEFAULT_INFLATION_RADIUS
    cost_scaling_factor: float = DEFAULT_COST_SCALING_FACTOR
    width: float = DEFAULT_LOCAL_WIDTH
    height: float = DEFAULT_LOCAL_HEIGHT
    obstacle_max_range: float = DEFAULT_OBSTACLE_MAX_RANGE
    raytrace_max_range: float = DEFAULT_RAYTRACE_MAX_RANGE
    track_unknown_space: bool = True
    obstacle_layer: bool = False  # the global costmap's lidar layer (tb4.nav.obstacle_layer)

    def __post_init__(self) -> None:
        for name in ("resolution", "robot_radius", "width", "height", "obstacle_max_range", "raytrace_max_range"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"CostmapParams.{name} must be a positive number, got {value}")
        if not (math.isfinite(self.inflation_radius) and self.inflation_radius >= 0):
            raise ValueError(f"CostmapParams.inflation_radius must be >= 0, got {self.inflation_radius}")
        if not (math.isfinite(self.cost_scaling_factor) and self.cost_scaling_factor >= 0):
            raise ValueError(f"CostmapParams.cost_scaling_factor must be >= 0, got {self.cost_scaling_factor}")

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any], source: str | Path | None = None) -> CostmapParams:
        """Build from a flat mapping with the field names; unknown keys are reported with a suggestion."""
        names = [f.name for f in cls.__dataclass_fields__.values()]  # type: ignore[attr-defined]
        check_keys(mapping, names, source)
        kwargs: dict[str, Any] = {}
        for key, value in mapping.items():
            if key in ("track_unknown_space", "obstacle_layer"):
                kwargs[key] = as_bool(value, source, key)
            else:
                kwargs[key] = as_float(value, source, key, minimum=0.0)
        try:
            return cls(**kwargs)
        except ValueError as exc:
            raise ConfigError(source, None, f"{exc}; use a positive value") from None

    @property
    def inflation_cells(self) -> int:
        """How many cells inflation can reach (Nav2's cell_inflation_radius)."""
        return int(math.ceil(self.inflation_radius / self.resolution))


def inflation_cost(distance: np.ndarray | float, params: CostmapParams) -> Any:
    """Nav2's inflation cost for a distance (metres) to the nearest lethal cell.

    0 -> LETHAL, <= robot_radius -> INSCRIBED, <= inflation_radius -> (uint8)(252 * exp(-k (d - r))), else 0.
    Returns an int for a scalar and a uint8 array for an array.
    """
    d = np.asarray(distance, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        decay = np.floor(MAX_NON_OBSTACLE * np.exp(-params.cost_scaling_factor * (d - params.robot_radius)))
    cost = np.where(d <= params.inflation_radius, np.clip(decay, 0, MAX_NON_OBSTACLE), 0.0)
    cost = np.where(d <= params.robot_radius, INSCRIBED, cost)
    cost = np.where(d <= 0.0, LETHAL, cost).astype(np.uint8)
    return int(cost) if cost.ndim == 0 else cost


def inflate(data: np.ndarray, resolution: float, params: CostmapParams) -> np.ndarray:
    """Inflate LETHAL cells of a uint8 grid (Nav2 inflation layer, inflate_unknown false).

    Each cell gets max(own cost, inflation cost of its distance to the nearest LETHAL cell centre); an unknown
    cell is only overwritten when the inflation makes it INSCRIBED (as Nav2 does).
    """
    data = np.asarray(data, dtype=np.uint8)
    lethal = data == LETHAL
    if not lethal.any() or params.inflation_radius <= 0:
        return data.copy()
    dist = distance_to_marked(lethal, resolution)
    cost = inflation_cost(dist, params)
    out = np.maximum(data, cost)
    unknown = data == NO_INFORMATION
    out[unknown] = np.where(cost[unknown] >= INSCRIBED, cost[unknown], NO_INFORMATION)
    return out


def inflation_table(resolution: float, params: CostmapParams) -> tuple[np.ndarray, int]:
    """inflate()'s costs by cell offset, for stamping around LETHAL cells (tb4.nav._costmapkernel).

    A (2k+1, 2k+1) uint8 table: inflation_cost of each offset's distance, computed as scipy's distance transform
    computes it (sqrt((dr * res)^2 + (dc * res)^2)), with k reaching past every offset of non-zero cost. The
    cost is non-increasing in distance, so the largest stamp on a cell is its nearest LETHAL cell's cost: what
    inflate() gives. Inflation off (inflation_radius 0, where inflate() copies the grid): an empty table, k = -1.
    """
    if params.inflation_radius <= 0:
        return np.zeros(0, dtype=np.uint8), -1
    k = int(math.ceil(max(params.inflation_radius, params.robot_radius) / resolution)) + 1
    offsets = np.arange(-k, k + 1).astype(np.float64) * resolution
    squares = offsets * offsets
    table = inflation_cost(np.sqrt(squares[:, None] + squares[None, :]), params)
    return np.ascontiguousarray(table, dtype=np.uint8), k


def stamping_is_exact(table: np.ndarray, k: int) -> bool:
    """Whether stamping `table` (inflation_table's) gives inflate()'s costs: offsets at the same cell distance
    (dr^2 + dc^2) have the same cost, and the cost never rises with that distance. The distance transform picks
    one nearest LETHAL cell and stamping takes the largest cost over all of them, so the two agree exactly when
    this holds; a float distance that rounds differently for two offsets at the same distance, on a cost step,
    would break it (re-inflate with inflate() then)."""
    if k < 0:
        return True
    offsets = np.arange(-k, k + 1, dtype=np.int64)
    squares = (offsets[:, None] ** 2 + offsets[None, :] ** 2).ravel()
    order = np.argsort(squares, kind="stable")
    dist, cost = squares[order], np.asarray(table, dtype=np.int64).reshape(-1)[order]
    same = dist[1:] == dist[:-1]
    return bool(np.all(cost[1:] <= cost[:-1]) and np.all(cost[1:][same] == cost[:-1][same]))


def _overlap_ranges(n_out: int, out_res: float, n_in: int, in_res: float) -> tuple[np.ndarray, np.ndarray]:
    """For each output cell along one axis, the first and last input cell it overlaps (inclusive)."""
    k = np.arange(n_out, dtype=np.float64)
    eps = 1e-9
    lo = np.floor(k * out_res / in_res + eps).astype(np.int64)
    hi = np.ceil((k + 1) * out_res / in_res - eps).astype(np.int64) - 1
    return np.clip(lo, 0, n_in - 1), np.clip(np.maximum(hi, lo), 0, n_in - 1)


def _box_any(mask: np.ndarray, rlo: np.ndarray, rhi: np.ndarray, clo: np.ndarray, chi: np.ndarray) -> np.ndarray:
    """Whether any True lies in each box [rlo..rhi] x [clo..chi], via a summed-area table.

    The table is summed in place, in 32 bits while every count fits: for a warehouse map, many times faster in a
    fresh process than in 64 bits with a temporary."""
    dtype = np.int32 if mask.size < 2**31 else np.int64
    sat = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), dtype=dtype)
    np.cumsum(mask, axis=0, dtype=dtype, out=sat[1:, 1:])
    np.cumsum(sat[1:, 1:], axis=1, out=sat[1:, 1:])
    r0, r1 = rlo[:, None], rhi[:, None] + 1
    c0, c1 = clo[None, :], chi[None, :] + 1
    return (sat[r1, c1] - sat[r0, c1] - sat[r1, c0] + sat[r0, c0]) > 0


def static_layer_from_map(grid: OccupancyMap, params: CostmapParams) -> Costmap2D:
    """Resample an OccupancyMap to params.resolution (Nav2 static layer semantics, trinary).

    A costmap cell is LETHAL if any map cell overlapping it is occupied, else NO_INFORMATION if any overlapping
    map cell is unknown (with track_unknown_space; FREE otherwise), else FREE. Same origin as the map.
    """
    res = params.resolution
    rows = max(1, int(math.ceil(grid.size_y / res - 1e-9)))
    cols = max(1, int(math.ceil(grid.size_x / res - 1e-9)))
    rlo, rhi = _overlap_ranges(rows, res, grid.height, grid.resolution)
    clo, chi = _overlap_ranges(cols, res, grid.width, grid.resolution)
    occupied = _box_any(grid.data >= OCCUPIED_THRESHOLD, rlo, rhi, clo, chi)
    data = np.zeros((rows, cols), dtype=np.uint8)
    if params.track_unknown_space:
        data[_box_any(grid.data < 0, rlo, rhi, clo, chi)] = NO_INFORMATION
    data[occupied] = LETHAL
    return Costmap2D(data, res, grid.origin_x, grid.origin_y, layer="static")


@dataclass(frozen=True, eq=False)
class StaticLayers:
    """The static layer a GlobalCostmap built from `grid` with `params`, and its inflation: read only once built, so
    a world reset's new costmap on the same map takes them instead of resampling and inflating the map again (the
    largest part of a reset)."""

    grid: OccupancyMap
    params: CostmapParams
    static: Costmap2D
    inflated: np.ndarray

    def fit(self, grid: OccupancyMap, params: CostmapParams) -> bool:
        """Whether these are what `grid` with `params` builds: the same map object, equal parameters."""
        return self.grid is grid and self.params == params


class GlobalCostmap:
    """The global costmap: static layer (the map, resampled) + obstacle layer (params.obstacle_layer) + inflation,
    Nav2's global_costmap.

    Args:
        grid: the map.
        params: its parameters (default: CostmapParams()).
        layers: static layers built before from this map (`layers` of a costmap built from it), taken when they fit
            `grid` and `params`; else built anew.
    """

    def __init__(
        self, grid: OccupancyMap, params: CostmapParams | None = None, layers: StaticLayers | None = None
    ) -> None:
        self.params = params or CostmapParams()
        self.static: Costmap2D
        self.costmap: Costmap2D
        self._inflated: np.ndarray
        self.layers: StaticLayers
        self.obstacles: Any = None  # GlobalObstacleLayer when enabled
        self.set_map(grid, layers)

    def set_map(self, grid: OccupancyMap, layers: StaticLayers | None = None) -> None:
        """Rebuild from a new map (LoadMap); lidar marks of the old map are dropped. `layers`: as in the constructor."""
        if layers is None or not layers.fit(grid, self.params):
            static = static_layer_from_map(grid, self.params)
            layers = StaticLayers(grid, self.params, static, inflate(static.data, self.params.resolution, self.params))
        self.layers = layers
        self.static, self._inflated = layers.static, layers.inflated
        if self.params.obstacle_layer:
            from tb4.nav.obstacle_layer import GlobalObstacleLayer  # noqa: PLC0415 - it builds on this module

            self.obstacles = GlobalObstacleLayer(self.static, self._inflated, self.params)
        self.clear()

    def clear(self) -> None:
        """ClearEntireCostmap: static + inflation, without lidar marks."""
        if self.obstacles is not None:
            self.obstacles.clear()
            self.costmap = self.obstacles.costmap
            return
        self.costmap = Costmap2D(
            self._inflated.copy(), self.static.resolution, self.static.origin_x, self.static.origin_y, layer="global"
        )

    def update_obstacles(self, sensor_x: float, sensor_y: float, hits: np.ndarray, free_ends: np.ndarray) -> None:
        """Mark/clear the obstacle layer from one scan (map frame); nothing when the layer is disabled."""
        if self.obstacles is not None:
            self.obstacles.update(sensor_x, sensor_y, hits, free_ends)
            self.costmap = self.obstacles.costmap

    def clear_around(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapAroundRobot: lidar marks inside the square of side reset_distance at (x, y)."""
        if self.obstacles is not None:
            self.obstacles.clear_around(x, y, reset_distance)
            self.costmap = self.obstacles.costmap

    def clear_except_region(self, x: float, y: float, reset_distance: float) -> None:
        """ClearCostmapExceptRegion: lidar marks outside that square."""
        if self.obstacles is not None:
            self.obstacles.clear_except_region(x, y, reset_distance)
            self.costmap = self.obstacles.costmap
