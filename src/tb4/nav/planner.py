"""Global planner: NavFn-like optimal grid search over a Nav2 costmap, plus planning through poses.

Why a cost-weighted search rather than shortest distance: entering a cell costs neutral_cost + cost_factor *
cost (NavFn's formula), so the optimum keeps away from walls and runs down the middle of aisles, which is what
the TurtleBot 4 does with NavFn. The search itself (A* with a consistent octile heuristic, so the result is
optimal for this cost model) runs in the small C kernel tb4.nav._gridsearch; this module checks inputs, snaps
goals within tolerance like NavFn and turns cells into poses.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from tb4.core.kernels import load_kernel
from tb4.nav.costmap import INSCRIBED, LETHAL, MAX_NON_OBSTACLE, NO_INFORMATION, Costmap2D

__all__ = [
    "PlanError",
    "PlanResult",
    "Planner",
    "to_path_code",
    "to_through_poses_code",
    "cell_weights",
    "DEFAULT_TOLERANCE",
    "NEUTRAL_COST",
    "COST_FACTOR",
    "UNKNOWN_COST",
]

# NavFn defaults (nav2_navfn_planner): COST_NEUTRAL 50, COST_FACTOR 0.8, unknown -> COST_OBS - 1 = 253.
NEUTRAL_COST = 50.0
COST_FACTOR = 0.8
UNKNOWN_COST = 253.0
DEFAULT_TOLERANCE = 0.5
# A start inside the inscribed band (docked, or pushed against a wall) may leave through inscribed cells
# within this distance; everywhere else inscribed cells are impassable for the robot centre.
ESCAPE_RADIUS = 0.3


class PlanError(IntEnum):
    """Why a plan failed (mapped to the ComputePathToPose / ComputePathThroughPoses error codes).

    The names are Nav2's result-code names; TF_ERROR is a request made before the robot is localized."""

    NONE = 0
    START_OUTSIDE_MAP = 1
    GOAL_OUTSIDE_MAP = 2
    START_OCCUPIED = 3
    GOAL_OCCUPIED = 4
    NO_VALID_PATH = 5
    NO_VIAPOINTS_GIVEN = 6
    TIMEOUT = 7
    INVALID_PLANNER = 8
    TF_ERROR = 9


_PATH_CODES = {
    PlanError.NONE: 0,
    PlanError.INVALID_PLANNER: 201,
    PlanError.TF_ERROR: 202,
    PlanError.START_OUTSIDE_MAP: 203,
    PlanError.GOAL_OUTSIDE_MAP: 204,
    PlanError.START_OCCUPIED: 205,
    PlanError.GOAL_OCCUPIED: 206,
    PlanError.TIMEOUT: 207,
    PlanError.NO_VALID_PATH: 208,
}
_THROUGH_CODES = {
    PlanError.NONE: 0,
    PlanError.INVALID_PLANNER: 301,
    PlanError.TF_ERROR: 302,
    PlanError.START_OUTSIDE_MAP: 303,
    PlanError.GOAL_OUTSIDE_MAP: 304,
    PlanError.START_OCCUPIED: 305,
    PlanError.GOAL_OCCUPIED: 306,
    PlanError.TIMEOUT: 307,
    PlanError.NO_VALID_PATH: 308,
    PlanError.NO_VIAPOINTS_GIVEN: 309,
}


def to_path_code(error: PlanError) -> int:
    """nav2_msgs/action/ComputePathToPose error_code (200 UNKNOWN for anything without its own code)."""
    return _PATH_CODES.get(PlanError(error), 200)


def to_through_poses_code(error: PlanError) -> int:
    """nav2_msgs/action/ComputePathThroughPoses error_code (300 UNKNOWN for anything without its own code)."""
    return _THROUGH_CODES.get(PlanError(error), 300)


@dataclass
class PlanResult:
    """A plan: (N, 3) poses x, y, yaw (yaw along the path, the last one the goal's), or an error and why."""

    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    error: PlanError = PlanError.NONE
    message: str = ""
    planning_time: float = 0.0

    @property
    def ok(self) -> bool:
        return self.error == PlanError.NONE


def cell_weights(
    data: np.ndarray,
    neutral_cost: float = NEUTRAL_COST,
    cost_factor: float = COST_FACTOR,
    allow_unknown: bool = True,
    unknown_cost: float = UNKNOWN_COST,
) -> np.ndarray:
    """Per-cell traversal weight of the search's cost model (inf where the robot centre may not enter).

    Entering a cell costs step * weight, step 1 or sqrt(2). Shared by the wrapper, the tests and the benchmark
    so the reference Dijkstra uses exactly the same graph.
    """
    lut = neutral_cost + cost_factor * np.arange(256, dtype=np.float64)
    lut[INSCRIBED:] = np.inf
    if allow_unknown:
        lut[NO_INFORMATION] = unknown_cost
    return lut[np.asarray(data, dtype=np.uint8)]


def _as_pose(pose: Sequence[float], what: str) -> tuple[float, float, float] | str:
    """(x, y, yaw) as floats, or an error message."""
    try:
        values = [float(v) for v in pose]
    except (TypeError, ValueError):
        return f"{what} pose must be a sequence of numbers (x, y[, yaw]), got {pose!r}"
    if len(values) not in (2, 3):
        return f"{what} pose must have 2 or 3 values (x, y[, yaw]), got {len(values)}"
    if len(values) == 2:
        values.append(0.0)
    if not all(math.isfinite(v) for v in values):
        return f"{what} pose is non-finite (NaN or infinite): {tuple(values)}"
    return (values[0], values[1], values[2])


class Planner:
    """NavFn-like planner (GridBased): optimal 8-connected search, goal tolerance, allow_unknown."""

    def __init__(
        self,
        tolerance: float = DEFAULT_TOLERANCE,
        allow_unknown: bool = True,
        neutral_cost: float = NEUTRAL_COST,
        cost_factor: float = COST_FACTOR,
        unknown_cost: float = UNKNOWN_COST,
        escape_radius: float = ESCAPE_RADIUS,
    ) -> None:
        self._gridsearch = load_kernel("tb4.nav._gridsearch")
        for name, value in (("tolerance", tolerance), ("escape_radius", escape_radius)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"Planner {name} must be a finite number >= 0, got {value}")
        if not (math.isfinite(neutral_cost) and neutral_cost > 0):
            raise ValueError(f"Planner neutral_cost must be > 0, got {neutral_cost}")
        if not (math.isfinite(cost_factor) and cost_factor >= 0):
            raise ValueError(f"Planner cost_factor must be >= 0, got {cost_factor}")
        if not (math.isfinite(unknown_cost) and unknown_cost > 0):
            raise ValueError(f"Planner unknown_cost must be > 0, got {unknown_cost}")
        self.tolerance = float(tolerance)
        self.allow_unknown = bool(allow_unknown)
        self.neutral_cost = float(neutral_cost)
        self.cost_factor = float(cost_factor)
        self.unknown_cost = float(unknown_cost)
        self.escape_radius = float(escape_radius)

    # --- public API ----------------------------------------------------------------------------------
    def plan(self, costmap: Costmap2D, start: Sequence[float], goal: Sequence[float]) -> PlanResult:
        """ComputePathToPose: the optimal path from start to goal (or the nearest reachable cell within
        tolerance of it), as poses from start to goal."""
        t0 = time.perf_counter()
        result = self._plan(costmap, start, goal)
        result.planning_time = time.perf_counter() - t0
        return result

    def plan_through(self, costmap: Costmap2D, start: Sequence[float], goals: Sequence[Sequence[float]]) -> PlanResult:
        """ComputePathThroughPoses: optimal legs start -> goals[0] -> goals[1] ..., concatenated in order."""
        t0 = time.perf_counter()
        goals = list(goals)
        if not goals:
            return PlanResult(
                error=PlanError.NO_VIAPOINTS_GIVEN,
                message="no goals given: pass at least one pose to plan through",
                planning_time=time.perf_counter() - t0,
            )
        pieces: list[np.ndarray] = []
        current: Sequence[float] = start
        for i, goal in enumerate(goals):
            leg = self._plan(costmap, current, goal)
            if not leg.ok:
                leg.message = f"goal {i} of {len(goals)}: {leg.message}"
                leg.planning_time = time.perf_counter() - t0
                return leg
            pieces.append(leg.path if not pieces else leg.path[1:])
            current = tuple(leg.path[-1])
        path = np.concatenate(pieces, axis=0)
        return PlanResult(path=path, planning_time=time.perf_counter() - t0)

    # --- implementation ------------------------------------------------------------------------------
    def _fail(self, error: PlanError, message: str) -> PlanResult:
        return PlanResult(error=error, message=message)

    def _traversable(self, data: np.ndarray) -> np.ndarray:
        ok = data < INSCRIBED
        if self.allow_unknown:
            ok |= data == NO_INFORMATION
        return ok

    def _search(self, data: np.ndarray, start: int, goal: int) -> list[int] | None:
        rows, cols = data.shape
        return self._gridsearch.astar(
            data,
            cols,
            rows,
            start,
            goal,
            self.neutral_cost,
            self.cost_factor,
            self.allow_unknown,
            self.unknown_cost,
        )

    def _escape_costs(self, costmap: Costmap2D, srow: int, scol: int) -> np.ndarray:
        """Costs with the inscribed cells near an inscribed start made passable (at the highest cost)."""
        data = costmap.data.copy()
        r = int(math.ceil(self.escape_radius / costmap.resolution))
        r0, r1 = max(0, srow - r), min(costmap.rows, srow + r + 1)
        c0, c1 = max(0, scol - r), min(costmap.cols, scol + r + 1)
        rr, cc = np.mgrid[r0:r1, c0:c1]
        near = np.hypot(rr - srow, cc - scol) * costmap.resolution <= self.escape_radius
        window = data[r0:r1, c0:c1]
        window[near & (window == INSCRIBED)] = MAX_NON_OBSTACLE
        return data

    def _plan(self, costmap: Costmap2D, start_in: Sequence[float], goal_in: Sequence[float]) -> PlanResult:
        start = _as_pose(start_in, "start")
        if isinstance(start, str):
            return self._fail(PlanError.START_OUTSIDE_MAP, start)
        goal = _as_pose(goal_in, "goal")
        if isinstance(goal, str):
            return self._fail(PlanError.GOAL_OUTSIDE_MAP, goal)
        sx, sy, _ = start
        gx, gy, gyaw = goal
        if not costmap.in_bounds(sx, sy):
            return self._fail(PlanError.START_OUTSIDE_MAP, f"start ({sx:.2f}, {sy:.2f}) is outside the costmap")
        if not costmap.in_bounds(gx, gy):
            return self._fail(PlanError.GOAL_OUTSIDE_MAP, f"goal ({gx:.2f}, {gy:.2f}) is outside the costmap")
        srow, scol = costmap.world_to_cell(sx, sy)
        start_cost = int(costmap.data[srow, scol])
        if start_cost == LETHAL:
            return self._fail(PlanError.START_OCCUPIED, f"start ({sx:.2f}, {sy:.2f}) is in an obstacle")
        data = costmap.data
        if start_cost == INSCRIBED:
            data = self._escape_costs(costmap, srow, scol)
        cols = costmap.cols
        start_idx = srow * cols + scol
        grow, gcol = costmap.world_to_cell(gx, gy)
        goal_idx = grow * cols + gcol
        traversable = self._traversable(data)

        cells: list[int] | None = None
        snapped = False
        tried = -1
        if traversable[grow, gcol] or goal_idx == start_idx:
            cells = self._search(data, start_idx, goal_idx)
            tried = goal_idx
        if cells is None:
            candidates = self._goal_candidates(costmap, traversable, gx, gy)
            if candidates.size == 0:
                return self._fail(
                    PlanError.GOAL_OCCUPIED,
                    f"goal ({gx:.2f}, {gy:.2f}) is in an obstacle and no free cell lies within the "
                    f"tolerance of {self.tolerance} m",
                )
            # nearest candidate first: if it is reachable (the usual case) no reachability analysis is needed
            if int(candidates[0]) != tried:
                cells = self._search(data, start_idx, int(candidates[0]))
            if cells is None:
                mask = traversable.copy()
                mask.flat[start_idx] = True
                from scipy import ndimage  # here, not at import: only an unreachable goal needs it

                labels, _ = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
                reachable = candidates[labels.flat[candidates] == labels.flat[start_idx]]
                if reachable.size == 0:
                    return self._fail(
                        PlanError.NO_VALID_PATH,
                        f"no path from ({sx:.2f}, {sy:.2f}) to ({gx:.2f}, {gy:.2f}): the goal is not reachable",
                    )
                cells = self._search(data, start_idx, int(reachable[0]))
                if cells is None:  # pragma: no cover - labels and search use the same 8-connected graph
                    return self._fail(PlanError.NO_VALID_PATH, "goal not reachable")
            snapped = cells[-1] != goal_idx
        return PlanResult(path=self._to_poses(costmap, cells, (sx, sy), (gx, gy, gyaw), snapped))

    def _goal_candidates(self, costmap: Costmap2D, traversable: np.ndarray, gx: float, gy: float) -> np.ndarray:
        """Flat indices of traversable cells whose centre is within tolerance of the goal, nearest first."""
        res = costmap.resolution
        r = int(math.ceil(self.tolerance / res)) + 1
        grow, gcol = costmap.world_to_cell(gx, gy)
        r0, r1 = max(0, grow - r), min(costmap.rows, grow + r + 1)
        c0, c1 = max(0, gcol - r), min(costmap.cols, gcol + r + 1)
        rr, cc = np.mgrid[r0:r1, c0:c1]
        cx = costmap.origin_x + (cc + 0.5) * res
        cy = costmap.origin_y + (rr + 0.5) * res
        dist = np.hypot(cx - gx, cy - gy)
        ok = traversable[r0:r1, c0:c1] & (dist <= self.tolerance + 1e-9)
        flat = (rr * costmap.cols + cc)[ok]
        order = np.lexsort((flat, dist[ok]))  # by distance, ties by index: deterministic
        return flat[order].astype(np.int64)

    @staticmethod
    def _to_poses(
        costmap: Costmap2D,
        cells: list[int],
        start_xy: tuple[float, float],
        goal: tuple[float, float, float],
        snapped: bool,
    ) -> np.ndarray:
        idx = np.asarray(cells, dtype=np.int64)
        rows, cols = np.divmod(idx, costmap.cols)
        xy = np.empty((len(idx), 2))
        xy[:, 0] = costmap.origin_x + (cols + 0.5) * costmap.resolution
        xy[:, 1] = costmap.origin_y + (rows + 0.5) * costmap.resolution
        xy[0] = start_xy
        if not snapped:
            if len(xy) == 1:
                xy = np.vstack([xy, goal[:2]])
            else:
                xy[-1] = goal[:2]
        if len(xy) == 2 and np.allclose(xy[0], xy[1], atol=1e-12, rtol=0.0):
            xy = xy[1:]
        n = len(xy)
        path = np.empty((n, 3))
        path[:, :2] = xy
        if n > 1:
            # heading towards the point two ahead: follows the path without the 45 degree zigzag of the grid
            ahead = xy[np.minimum(np.arange(n) + 2, n - 1)]
            path[:, 2] = np.arctan2(ahead[:, 1] - xy[:, 1], ahead[:, 0] - xy[:, 0])
        path[-1, 2] = goal[2]
        return path
