"""Global planner: optimality against a reference Dijkstra, Nav2 error semantics, goal tolerance, path shape."""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from tb4.nav import _gridsearch
from tb4.nav.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap2D, CostmapParams, inflate
from tb4.nav.planner import PlanError, Planner, cell_weights, to_path_code, to_through_poses_code

pytestmark = pytest.mark.core

RES = 0.06
_MOVES = [(0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)]


def _reference_graph(data: np.ndarray, allow_unknown: bool) -> sp.csr_matrix:
    """The same 8-connected graph the planner searches: u -> v costs step * weight(v)."""
    rows, cols = data.shape
    w = cell_weights(data, allow_unknown=allow_unknown).ravel()
    idx = np.arange(rows * cols).reshape(rows, cols)
    src, dst, cost = [], [], []
    for dr, dc in _MOVES:
        a = idx[max(0, -dr) : rows - max(0, dr), max(0, -dc) : cols - max(0, dc)].ravel()
        b = idx[max(0, dr) : rows - max(0, -dr), max(0, dc) : cols - max(0, -dc)].ravel()
        c = w[b] * math.hypot(dr, dc)
        ok = np.isfinite(c)
        src.append(a[ok])
        dst.append(b[ok])
        cost.append(c[ok])
    n = rows * cols
    return sp.csr_matrix((np.concatenate(cost), (np.concatenate(src), np.concatenate(dst))), shape=(n, n))


def _path_cost(data: np.ndarray, cells: list[int], allow_unknown: bool) -> float:
    cols = data.shape[1]
    w = cell_weights(data, allow_unknown=allow_unknown).ravel()
    total = 0.0
    for a, b in zip(cells[:-1], cells[1:], strict=True):
        (ra, ca), (rb, cb) = divmod(a, cols), divmod(b, cols)
        assert max(abs(ra - rb), abs(ca - cb)) == 1, "consecutive cells must be 8-neighbours"
        assert np.isfinite(w[b]), "path enters a blocked cell"
        total += w[b] * math.hypot(ra - rb, ca - cb)
    return total


def _random_costmap(rng: np.random.Generator, rows: int, cols: int, unknown: bool) -> np.ndarray:
    """Random blobs of walls, inflated with the Nav2 formula, plus random soft costs and unknown patches."""
    data = np.zeros((rows, cols), dtype=np.uint8)
    data[rng.random((rows, cols)) < 0.012] = LETHAL
    data = inflate(data, RES, CostmapParams())
    soft = rng.integers(0, 200, size=(rows, cols)).astype(np.uint8)
    patch = rng.random((rows, cols)) < 0.3
    data = np.where(patch & (data < soft), soft, data).astype(np.uint8)
    if unknown:
        data[rng.random((rows, cols)) < 0.05] = NO_INFORMATION
    return data


@pytest.mark.parametrize("seed", range(24))
def test_search_is_optimal_against_reference_dijkstra(seed: int) -> None:
    rng = np.random.default_rng(seed)
    rows, cols = int(rng.integers(20, 45)), int(rng.integers(20, 45))
    allow_unknown = bool(seed % 2)
    data = _random_costmap(rng, rows, cols, unknown=seed % 3 != 0)
    start = int(rng.choice(np.flatnonzero(data.ravel() < INSCRIBED)))
    graph = _reference_graph(data, allow_unknown)
    dist = dijkstra(graph, indices=start)
    reached = 0
    for goal in rng.integers(rows * cols, size=8):
        goal = int(goal)
        cells = _gridsearch.astar(data, cols, rows, start, goal, 50.0, 0.8, allow_unknown, 253.0)
        if not np.isfinite(dist[goal]):
            assert cells is None
            continue
        assert cells is not None and cells[0] == start and cells[-1] == goal
        assert _path_cost(data, cells, allow_unknown) == pytest.approx(dist[goal], rel=1e-6, abs=1e-9)
        reached += 1
    assert reached >= 2  # the map is not so cluttered that the comparison is vacuous


def test_concurrent_searches_match_sequential_ones() -> None:
    """The search releases the GIL and reuses its scratch arrays: threads must not interfere."""
    rng = np.random.default_rng(7)
    jobs = []
    for k in range(8):
        rows, cols = 30 + 7 * k, 60 - 3 * k  # different sizes, so scratch arrays are grown and handed around
        data = _random_costmap(rng, rows, cols, unknown=True)
        free = np.flatnonzero(data.ravel() < INSCRIBED)
        start, goal = (int(v) for v in rng.choice(free, size=2, replace=False))
        jobs.append((data, cols, rows, start, goal))
    expected = [_gridsearch.astar(d, c, r, s, g) for d, c, r, s, g in jobs]
    with ThreadPoolExecutor(max_workers=4) as pool:
        for _ in range(5):
            got = list(pool.map(lambda job: _gridsearch.astar(*job), jobs))
            assert got == expected


def test_search_argument_checks() -> None:
    data = np.zeros((4, 5), dtype=np.uint8)
    with pytest.raises(ValueError):
        _gridsearch.astar(data, 4, 4, 0, 1)
    with pytest.raises(IndexError):
        _gridsearch.astar(data, 5, 4, 0, 20)
    assert _gridsearch.astar(data, 5, 4, 7, 7) == [7]
    assert _gridsearch.astar(bytes(data), 5, 4, 0, 19) is not None


def _grid_costmap(data: np.ndarray) -> Costmap2D:
    return Costmap2D(data, RES, 0.0, 0.0)


def _centre(cm: Costmap2D, row: int, col: int) -> tuple[float, float]:
    return cm.cell_to_world(row, col)


@pytest.mark.parametrize("seed", range(6))
def test_planner_paths_are_optimal_and_collision_free(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    data = _random_costmap(rng, 40, 50, unknown=True)
    cm = _grid_costmap(data)
    free = np.flatnonzero(data.ravel() < INSCRIBED)
    start, goal = (int(v) for v in rng.choice(free, size=2, replace=False))
    dist = dijkstra(_reference_graph(data, True), indices=start)
    (sr, sc), (gr, gc) = divmod(start, 50), divmod(goal, 50)
    result = Planner().plan(cm, (*_centre(cm, sr, sc), 0.0), (*_centre(cm, gr, gc), 1.0))
    if not np.isfinite(dist[goal]):
        assert result.error == PlanError.NO_VALID_PATH
        return
    assert result.ok, result.message
    rows, cols, inside = cm.cells_of(result.path)
    assert inside.all()
    cells = (rows * 50 + cols).tolist()
    assert _path_cost(data, cells, True) == pytest.approx(dist[goal], rel=1e-6)
    assert (cm.costs_at(result.path) < INSCRIBED).sum() + (cm.costs_at(result.path) == NO_INFORMATION).sum() == len(
        cells
    )
    assert result.path[-1, 2] == 1.0


def _corridor(width_m: float, length_m: float = 10.0) -> Costmap2D:
    """A straight corridor along x, centre line y = 0, with one-cell walls, inflated."""
    rows = int(round(width_m / RES)) + 2
    cols = int(round(length_m / RES))
    data = np.zeros((rows, cols), dtype=np.uint8)
    data[0, :] = data[-1, :] = LETHAL
    data[:, 0] = data[:, -1] = LETHAL
    origin_y = -rows * RES / 2
    return Costmap2D(inflate(data, RES, CostmapParams()), RES, 0.0, origin_y)


def test_path_stays_in_middle_of_2m_corridor() -> None:
    cm = _corridor(2.0)
    result = Planner().plan(cm, (0.8, 0.6, 0.0), (9.2, -0.6, 0.0))
    assert result.ok, result.message
    middle = result.path[(result.path[:, 0] > 2.0) & (result.path[:, 0] < 8.0)]
    assert len(middle) > 50
    # outside the inflation of both walls (walls at |y| = 1.0, inflation 0.45 m)
    assert np.abs(middle[:, 1]).max() <= 1.0 - 0.45
    assert (cm.costs_at(middle) == 0).all()


def test_path_follows_centre_line_of_narrow_corridor() -> None:
    cm = _corridor(1.0)
    result = Planner().plan(cm, (0.8, 0.15, 0.0), (9.2, -0.15, 0.0))
    assert result.ok, result.message
    middle = result.path[(result.path[:, 0] > 2.0) & (result.path[:, 0] < 8.0)]
    assert np.abs(middle[:, 1]).max() <= RES
    assert abs(float(np.median(middle[:, 2]))) < 1e-9  # heading along the corridor


def _room_with_wall() -> Costmap2D:
    """6 x 6 m room; a wall block in the middle; an enclosed 1 x 1 m cell in the north-east."""
    n = 100
    data = np.zeros((n, n), dtype=np.uint8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = LETHAL
    data[35:65, 40:60] = LETHAL  # block from (2.4, 2.1) to (3.6, 3.9)
    data[75:95, 75] = data[75:95, 95] = LETHAL  # enclosure x 4.5..5.7, y 4.5..5.7
    data[75, 75:96] = data[95, 75:96] = LETHAL
    return Costmap2D(inflate(data, RES, CostmapParams()), RES, 0.0, 0.0)


def test_plan_reaches_goal_exactly_with_yaw() -> None:
    cm = _room_with_wall()
    result = Planner().plan(cm, (1.0, 3.0, 0.0), (5.0, 3.0, 1.2))
    assert result.ok and result.error == PlanError.NONE
    assert result.path.shape[1] == 3
    assert tuple(result.path[0, :2]) == (1.0, 3.0)
    assert tuple(result.path[-1]) == (5.0, 3.0, 1.2)
    steps = np.hypot(*np.diff(result.path[:, :2], axis=0).T)
    assert steps.max() <= 2 * RES  # cell centres, except the exact start and goal at the ends
    assert (cm.costs_at(result.path) < INSCRIBED).all()
    assert result.planning_time > 0
    # went around the block
    assert np.abs(result.path[:, 1] - 3.0).max() > 0.6


@pytest.mark.parametrize(
    ("start", "goal", "error", "words"),
    [
        ((float("nan"), 1.0, 0.0), (2.0, 2.0, 0.0), PlanError.START_OUTSIDE_MAP, "non-finite"),
        ((1.0, 1.0, 0.0), (float("inf"), 2.0, 0.0), PlanError.GOAL_OUTSIDE_MAP, "non-finite"),
        ((1.0, 1.0, 0.0), (2.0, 2.0, float("nan")), PlanError.GOAL_OUTSIDE_MAP, "non-finite"),
        ((-1.0, 1.0, 0.0), (2.0, 2.0, 0.0), PlanError.START_OUTSIDE_MAP, "outside"),
        ((1.0, 1.0, 0.0), (2.0, 6.5, 0.0), PlanError.GOAL_OUTSIDE_MAP, "outside"),
        ((3.0, 3.0, 0.0), (1.0, 1.0, 0.0), PlanError.START_OCCUPIED, "obstacle"),
        ((1.0, 1.0, 0.0), (3.0, 3.0, 0.0), PlanError.GOAL_OCCUPIED, "tolerance"),
        ((1.0, 1.0, 0.0), (5.1, 5.1, 0.0), PlanError.NO_VALID_PATH, "not reachable"),
    ],
)
def test_bad_requests(start: tuple, goal: tuple, error: PlanError, words: str) -> None:
    cm = _room_with_wall()
    result = Planner().plan(cm, start, goal)
    assert not result.ok
    assert result.error == error
    assert words in result.message
    assert len(result.path) == 0
    codes = {
        PlanError.START_OUTSIDE_MAP: (203, 303),
        PlanError.GOAL_OUTSIDE_MAP: (204, 304),
        PlanError.START_OCCUPIED: (205, 305),
        PlanError.GOAL_OCCUPIED: (206, 306),
        PlanError.NO_VALID_PATH: (208, 308),
    }
    assert (to_path_code(result.error), to_through_poses_code(result.error)) == codes[error]
    through = Planner().plan_through(cm, start, [goal])
    assert through.error == error


def test_error_codes() -> None:
    assert to_path_code(PlanError.NONE) == 0
    assert [to_path_code(e) for e in PlanError if e != PlanError.NONE] == [203, 204, 205, 206, 208, 200, 207, 201, 202]
    assert to_path_code(PlanError.GOAL_OCCUPIED) == 206
    assert to_through_poses_code(PlanError.GOAL_OCCUPIED) == 306
    assert to_through_poses_code(PlanError.NO_VIAPOINTS_GIVEN) == 309
    assert to_through_poses_code(PlanError.NO_VALID_PATH) == 308


def test_goal_in_wall_snaps_to_nearest_free_cell_within_tolerance() -> None:
    cm = _room_with_wall()
    # 0.2 m inside the block's west face (x = 2.4): the nearest cell the robot centre may occupy is ~0.4 m away
    goal = (2.6, 3.0, 0.7)
    result = Planner(tolerance=0.5).plan(cm, (1.0, 3.0, 0.0), goal)
    assert result.ok, result.message
    end = result.path[-1]
    assert math.hypot(end[0] - goal[0], end[1] - goal[1]) <= 0.5
    assert cm.cost_at(end[0], end[1]) < INSCRIBED
    assert end[2] == 0.7
    # it is the nearest such cell
    rows, cols = np.nonzero(cm.data < INSCRIBED)
    xs, ys = (cols + 0.5) * RES, (rows + 0.5) * RES
    nearest = np.hypot(xs - goal[0], ys - goal[1]).min()
    assert math.hypot(end[0] - goal[0], end[1] - goal[1]) == pytest.approx(nearest)
    # with a smaller tolerance the same goal is refused
    assert Planner(tolerance=0.1).plan(cm, (1.0, 3.0, 0.0), goal).error == PlanError.GOAL_OCCUPIED


def test_unreachable_goal_falls_back_to_reachable_cell_within_tolerance() -> None:
    cm = _room_with_wall()
    # inside the enclosure, 0.22 m from its west wall: free cells just outside the wall are 0.4 m away
    result = Planner(tolerance=0.5).plan(cm, (1.0, 1.0, 0.0), (4.75, 5.1, 0.0))
    assert result.ok, result.message
    assert result.path[-1, 0] < 4.5


def test_start_in_inscribed_zone_is_allowed() -> None:
    cm = _room_with_wall()
    start = (0.15, 3.0, 0.0)  # 0.09 m from the west wall cell: inscribed
    assert cm.cost_at(*start[:2]) == INSCRIBED
    result = Planner().plan(cm, start, (1.5, 3.0, 0.0))
    assert result.ok, result.message
    costs = cm.costs_at(result.path)
    far = np.hypot(result.path[:, 0] - start[0], result.path[:, 1] - start[1]) > 0.3
    assert (costs[far] < INSCRIBED).all()


def test_unknown_space_respects_allow_unknown() -> None:
    data = np.zeros((30, 60), dtype=np.uint8)
    data[:, 25:35] = NO_INFORMATION
    cm = _grid_costmap(data)
    start, goal = (0.5, 0.9, 0.0), (3.2, 0.9, 0.0)
    assert Planner(allow_unknown=True).plan(cm, start, goal).ok
    assert Planner(allow_unknown=False).plan(cm, start, goal).error == PlanError.NO_VALID_PATH


def test_start_and_goal_in_same_cell() -> None:
    cm = _room_with_wall()
    result = Planner().plan(cm, (1.0, 1.0, 0.0), (1.01, 1.01, 0.5))
    assert result.ok
    assert tuple(result.path[-1]) == (1.01, 1.01, 0.5)
    assert tuple(result.path[0, :2]) == (1.0, 1.0)
    same = Planner().plan(cm, (1.0, 1.0, 0.0), (1.0, 1.0, 0.5))
    assert same.ok and len(same.path) == 1 and tuple(same.path[0]) == (1.0, 1.0, 0.5)


def test_plan_through_visits_goals_in_order() -> None:
    cm = _room_with_wall()
    goals = [(5.0, 1.0, 0.0), (5.0, 3.5, 1.0), (1.0, 5.0, 2.0)]
    result = Planner().plan_through(cm, (1.0, 1.0, 0.0), goals)
    assert result.ok, result.message
    visits = []
    for gx, gy, gyaw in goals:
        hits = np.flatnonzero(np.hypot(result.path[:, 0] - gx, result.path[:, 1] - gy) < 1e-9)
        assert len(hits) >= 1
        visits.append(int(hits[0]))
        assert result.path[hits[0], 2] == gyaw
    assert visits == sorted(visits)
    assert tuple(result.path[-1]) == goals[-1]
    # no duplicated joints
    assert (np.hypot(*np.diff(result.path[:, :2], axis=0).T) > 0).all()


def test_plan_through_errors() -> None:
    cm = _room_with_wall()
    empty = Planner().plan_through(cm, (1.0, 1.0, 0.0), [])
    assert empty.error == PlanError.NO_VIAPOINTS_GIVEN
    assert to_through_poses_code(empty.error) == 309
    bad = Planner().plan_through(cm, (1.0, 1.0, 0.0), [(5.0, 1.0, 0.0), (3.0, 3.0, 0.0)])
    assert bad.error == PlanError.GOAL_OCCUPIED
    assert to_through_poses_code(bad.error) == 306
    assert "goal 1 of 2" in bad.message


def test_planner_rejects_bad_settings() -> None:
    with pytest.raises(ValueError):
        Planner(tolerance=float("nan"))
    with pytest.raises(ValueError):
        Planner(neutral_cost=0.0)


def test_cell_weights_model() -> None:
    data = np.array([[0, 100, 252, 253, 254, 255]], dtype=np.uint8)
    w = cell_weights(data, allow_unknown=True)
    assert w.tolist() == [[50.0, 130.0, 50.0 + 0.8 * 252, math.inf, math.inf, 253.0]]
    assert math.isinf(cell_weights(data, allow_unknown=False)[0, 5])
