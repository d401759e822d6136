"""Path smoothing (Nav2 simple smoother semantics) and path validity (Nav2 IsPathValid).

Grid paths zigzag at 45 degree steps; smoothing pulls interior points towards their neighbours while a data
term keeps them near the original, so the controller gets a path it can follow without wobbling. A point is
never moved into a cell the robot centre may not occupy (cost >= INSCRIBED), so smoothing cannot create a
collision the planner avoided.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from tb4.nav.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap2D

__all__ = [
    "SmoothResult",
    "smooth_path",
    "is_path_valid",
    "path_yaws",
    "W_DATA",
    "W_SMOOTH",
    "TOLERANCE",
    "MAX_ITERATIONS",
    "MAX_DURATION",
]

# nav2_smoother SimpleSmoother defaults (max_duration is the SmoothPath action's default in BasicNavigator).
W_DATA = 0.2
W_SMOOTH = 0.3
TOLERANCE = 1e-10
MAX_ITERATIONS = 1000
MAX_DURATION = 2.0


@dataclass
class SmoothResult:
    """The smoothed (N, 3) path; was_completed False when max_duration or max_iterations ran out first;
    in_collision True when a collision check was requested and some pose lies in an obstacle."""

    path: np.ndarray
    was_completed: bool
    in_collision: bool = False
    iterations: int = 0


def path_yaws(xy: np.ndarray) -> np.ndarray:
    """Heading of each point along the path (central differences inside, one-sided at the ends)."""
    n = len(xy)
    if n < 2:
        return np.zeros(n)
    nxt = xy[np.minimum(np.arange(n) + 1, n - 1)]
    prv = xy[np.maximum(np.arange(n) - 1, 0)]
    d = nxt - prv
    return np.arctan2(d[:, 1], d[:, 0])


def _blocked(costmap: Costmap2D, xy: np.ndarray) -> np.ndarray:
    """Where the robot centre may not be: INSCRIBED/LETHAL cells and off the map (unknown is allowed, as Nav2)."""
    rows, cols, inside = costmap.cells_of(xy)
    cost = costmap.data[rows, cols]
    return ~inside | ((cost >= INSCRIBED) & (cost != NO_INFORMATION))


def smooth_path(
    path: np.ndarray,
    costmap: Costmap2D | None = None,
    *,
    w_data: float = W_DATA,
    w_smooth: float = W_SMOOTH,
    tolerance: float = TOLERANCE,
    max_iterations: int = MAX_ITERATIONS,
    max_duration: float = MAX_DURATION,
    check_for_collision: bool = False,
) -> SmoothResult:
    """Smooth the interior points of an (N, 2|3) path; the endpoints (position and yaw) stay fixed.

    Each iteration moves every interior point by w_data * (original - current) + w_smooth * (next + previous -
    2 * current) (all points at once); a point whose new position would be in a cell with cost >= INSCRIBED
    keeps its previous position. Stops when the total movement of an iteration is below `tolerance`.
    """
    arr = np.asarray(path, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] not in (2, 3):
        raise ValueError(f"path must be an (N, 2) or (N, 3) array, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("path contains NaN or infinite values")
    if not (w_data >= 0 and w_smooth >= 0 and w_data + 4 * w_smooth < 2):
        raise ValueError(
            f"w_data and w_smooth must be >= 0 with w_data + 4*w_smooth < 2 (else smoothing diverges), "
            f"got {w_data}, {w_smooth}"
        )
    original = arr[:, :2].copy()
    current = original.copy()
    n = len(current)
    completed = True
    iterations = 0
    if n > 2:
        deadline = time.perf_counter() + max(0.0, max_duration)
        completed = False
        while iterations < max_iterations:
            iterations += 1
            inner = current[1:-1]
            step = w_data * (original[1:-1] - inner) + w_smooth * (current[2:] + current[:-2] - 2.0 * inner)
            proposal = inner + step
            if costmap is not None:
                refuse = _blocked(costmap, proposal)
                proposal[refuse] = inner[refuse]
            change = float(np.abs(proposal - inner).sum())
            current[1:-1] = proposal
            if change < tolerance:
                completed = True
                break
            if time.perf_counter() > deadline:
                break
    out = np.empty((n, 3))
    out[:, :2] = current
    out[:, 2] = path_yaws(current)
    if arr.shape[1] == 3 and n > 0:
        out[0, 2] = arr[0, 2]
        out[-1, 2] = arr[-1, 2]
    in_collision = False
    if check_for_collision and costmap is not None and n > 0:
        cost = costmap.costs_at(out)
        in_collision = bool(((cost >= INSCRIBED) & (cost != NO_INFORMATION)).any())
    return SmoothResult(path=out, was_completed=completed, in_collision=in_collision, iterations=iterations)


def is_path_valid(
    costmap: Costmap2D,
    path: np.ndarray,
    max_cost: int = LETHAL,
    consider_unknown_as_obstacle: bool = False,
) -> tuple[bool, list[int]]:
    """Nav2 IsPathValid: (valid, indices of invalid poses). A pose is invalid off the map or when its cell
    cost >= max_cost; NO_INFORMATION counts only with consider_unknown_as_obstacle."""
    arr = np.asarray(path, dtype=np.float64)
    if arr.size == 0:
        return True, []
    if arr.ndim != 2 or arr.shape[1] < 2:
        raise ValueError(f"path must be an (N, 2) or (N, 3) array, got shape {arr.shape}")
    if not (isinstance(max_cost, (int, np.integer)) or (isinstance(max_cost, float) and math.isfinite(max_cost))):
        raise ValueError(f"max_cost must be a number, got {max_cost!r}")
    rows, cols, inside = costmap.cells_of(arr[:, :2])
    cost = costmap.data[rows, cols].astype(np.int64)
    unknown = cost == NO_INFORMATION
    bad = (cost >= max_cost) & ~unknown
    if consider_unknown_as_obstacle:
        bad |= unknown
    bad |= ~inside
    invalid = np.flatnonzero(bad).tolist()
    return (not invalid), invalid
