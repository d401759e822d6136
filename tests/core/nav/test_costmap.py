"""Costmaps: Nav2 cost values, inflation formula, map resampling, rolling local costmap with raytracing."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.nav.costmap import (
    FREE_SPACE,
    INSCRIBED,
    LETHAL,
    NO_INFORMATION,
    Costmap2D,
    CostmapParams,
    GlobalCostmap,
    inflate,
    inflation_cost,
    static_layer_from_map,
)
from tb4.nav.local_costmap import LocalCostmap

pytestmark = pytest.mark.core

P = CostmapParams()


def _nav2_cost(d: float) -> int:
    """Independent restatement of Nav2's InflationLayer::computeCost for a metric distance."""
    if d == 0:
        return 254
    if d <= 0.175:
        return 253
    if d > 0.45:
        return 0
    return int(252 * math.exp(-4.0 * (d - 0.175)))


def test_nav2_constants() -> None:
    assert (FREE_SPACE, INSCRIBED, LETHAL, NO_INFORMATION) == (0, 253, 254, 255)


@pytest.mark.parametrize(
    ("distance", "expected"),
    [
        (0.0, 254),
        (0.06, 253),
        (0.175, 253),
        (0.18, 247),
        (0.24, 194),
        (0.30, 152),
        (0.36, 120),
        (0.42, 94),
        (0.45, 83),
        (0.4501, 0),
        (2.0, 0),
    ],
)
def test_inflation_cost_exact_values(distance: float, expected: int) -> None:
    assert inflation_cost(distance, P) == expected
    assert _nav2_cost(distance) == expected


def test_inflation_cost_vectorized_matches_scalar() -> None:
    d = np.linspace(0.0, 0.6, 301)
    got = inflation_cost(d, P)
    assert got.dtype == np.uint8
    assert got.tolist() == [_nav2_cost(float(x)) for x in d]


def test_inflate_single_obstacle_cell_distances() -> None:
    grid = np.zeros((41, 41), dtype=np.uint8)
    grid[20, 20] = LETHAL
    out = inflate(grid, 0.06, P)
    # along a row: distances k * 0.06
    assert out[20, 20:30].tolist() == [254, 253, 253, 247, 194, 152, 120, 94, 0, 0]
    # diagonals: k * 0.06 * sqrt(2)
    for k in range(0, 7):
        assert out[20 + k, 20 + k] == _nav2_cost(k * 0.06 * math.sqrt(2)), k
    # symmetric, and exactly the formula everywhere
    rr, cc = np.mgrid[0:41, 0:41]
    dist = np.hypot(rr - 20, cc - 20) * 0.06
    expected = np.vectorize(_nav2_cost)(dist)
    assert np.array_equal(out, expected)


def test_inflate_keeps_unknown_unless_inscribed() -> None:
    grid = np.full((20, 20), NO_INFORMATION, dtype=np.uint8)
    grid[10, 5] = LETHAL
    out = inflate(grid, 0.06, P)
    assert out[10, 6] == INSCRIBED  # 0.06 m: overwritten
    assert out[10, 10] == NO_INFORMATION  # 0.30 m: stays unknown (Nav2 inflate_unknown false)
    assert out[10, 5] == LETHAL


def _map(data: np.ndarray, res: float = 0.03) -> OccupancyMap:
    return OccupancyMap(data=data, resolution=res, origin_x=-1.0, origin_y=-2.0)


def test_resample_003_to_006() -> None:
    data = np.zeros((10, 12), dtype=np.int8)
    data[3, 5] = 100  # costmap cell (1, 2)
    data[7, 0] = -1  # costmap cell (3, 0)
    data[8, 8] = -1  # costmap cell (4, 4) holds unknown and occupied -> lethal
    data[9, 9] = 100
    layer = static_layer_from_map(_map(data), P)
    assert layer.data.shape == (5, 6)
    assert (layer.origin_x, layer.origin_y, layer.resolution) == (-1.0, -2.0, 0.06)
    expected = np.zeros((5, 6), dtype=np.uint8)
    expected[1, 2] = LETHAL
    expected[3, 0] = NO_INFORMATION
    expected[4, 4] = LETHAL
    assert np.array_equal(layer.data, expected)
    untracked = static_layer_from_map(_map(data), CostmapParams(track_unknown_space=False))
    assert untracked.data[3, 0] == FREE_SPACE and untracked.data[1, 2] == LETHAL


def test_resample_004_straddling_cell_marks_both() -> None:
    data = np.zeros((3, 3), dtype=np.int8)  # 0.12 m square -> 2 x 2 costmap cells
    data[0, 1] = 100  # spans x in [0.04, 0.08): overlaps costmap columns 0 and 1
    layer = static_layer_from_map(_map(data, 0.04), P)
    assert layer.data.shape == (2, 2)
    assert layer.data.tolist() == [[LETHAL, LETHAL], [0, 0]]


def test_resample_warehouse_sized_map_shape() -> None:
    data = np.zeros((1674, 1006), dtype=np.int8)
    layer = static_layer_from_map(OccupancyMap(data, 0.03, -15.1, -25.0), P)
    assert layer.data.shape == (837, 503)


def _room() -> OccupancyMap:
    """4 x 4 m room at 0.03 m with 0.09 m walls, origin (-2, -2)."""
    data = np.zeros((134, 134), dtype=np.int8)
    data[:3, :] = data[-3:, :] = 100
    data[:, :3] = data[:, -3:] = 100
    return OccupancyMap(data, 0.03, -2.0, -2.0)


def test_global_costmap_static_plus_inflation_and_clear() -> None:
    gc = GlobalCostmap(_room(), P)
    cm = gc.costmap
    assert cm.layer == "global"
    assert cm.cost_at(-1.97, 0.0) == LETHAL
    assert cm.cost_at(0.0, 0.0) == FREE_SPACE
    # the 0.09 m wall covers costmap columns 0 and 1; then 0.06 m * k from the inner wall cell's centre
    row, col = cm.world_to_cell(0.0, 0.0)
    assert cm.data[row, :7].tolist() == [254, 254, 253, 253, 247, 194, 152]
    cm.data[row, col] = LETHAL  # someone scribbles on it
    gc.clear()
    assert gc.costmap.data[row, col] == FREE_SPACE
    assert cm.cost_at(100.0, 0.0) == NO_INFORMATION
    assert cm.cost_at(float("nan"), 0.0) == NO_INFORMATION


def test_global_costmap_set_map() -> None:
    gc = GlobalCostmap(_room(), P)
    data = np.zeros((50, 50), dtype=np.int8)
    data[25, 25] = 100
    gc.set_map(OccupancyMap(data, 0.03, 0.0, 0.0))
    assert gc.costmap.data.shape == (25, 25)
    assert gc.costmap.cost_at(0.76, 0.76) == LETHAL


def test_costmap2d_helpers() -> None:
    cm = Costmap2D(np.zeros((3, 4), dtype=np.uint8), 0.5, 1.0, 2.0)
    assert cm.world_to_cell(1.6, 2.1) == (0, 1)
    assert cm.cell_to_world(0, 1) == (1.75, 2.25)
    assert cm.in_bounds(2.9, 3.4) and not cm.in_bounds(3.1, 2.1) and not cm.in_bounds(0.9, 2.1)
    pts = np.array([[1.6, 2.1], [10.0, 2.0], [np.nan, 2.0]])
    assert cm.costs_at(pts).tolist() == [0, 255, 255]
    other = cm.copy()
    other.data[0, 0] = 9
    assert cm.data[0, 0] == 0


def _free_local(width: float = 3.0) -> LocalCostmap:
    return LocalCostmap(CostmapParams(width=width, height=width), None)


def test_local_costmap_window_follows_robot_on_cell_boundaries() -> None:
    lc = _free_local()
    lc.update(0.31, -0.2, np.zeros((0, 2)), 0.31, -0.2)
    cm = lc.costmap
    assert cm.data.shape == (50, 50)
    assert cm.layer == "local"
    for v in (cm.origin_x / 0.06, cm.origin_y / 0.06):
        assert abs(v - round(v)) < 1e-9
    assert cm.in_bounds(0.31 - 1.4, -0.2 + 1.4) and cm.in_bounds(0.31 + 1.4, -0.2 - 1.4)
    row, col = cm.world_to_cell(0.31, -0.2)
    assert (row, col) == (25, 25)


def test_local_costmap_marks_and_inflates_hits() -> None:
    lc = _free_local()
    lc.update(0.0, 0.0, np.array([[1.0, 0.03]]), 0.0, 0.0)
    cm = lc.costmap
    assert cm.cost_at(1.0, 0.03) == LETHAL
    assert cm.cost_at(1.0 - 0.06, 0.03) == INSCRIBED
    assert cm.cost_at(0.0, 0.0) == FREE_SPACE
    assert int(lc.obstacles.sum()) == 1


def test_local_costmap_raytrace_clears_moved_obstacle() -> None:
    lc = _free_local()
    lc.update(0.0, 0.0, np.array([[0.8, 0.03]]), 0.0, 0.0)
    assert lc.costmap.cost_at(0.8, 0.03) == LETHAL
    # the obstacle moved away along the same bearing: the ray to the new hit passes through the old cell
    lc.update(0.0, 0.0, np.array([[1.3, 0.03]]), 0.0, 0.0)
    assert lc.costmap.cost_at(1.3, 0.03) == LETHAL
    assert lc.costmap.cost_at(0.8, 0.03) < INSCRIBED
    assert int(lc.obstacles.sum()) == 1


def test_local_costmap_free_endpoints_clear_and_range_limits() -> None:
    lc = _free_local(width=8.0)
    lc.update(0.0, 0.0, np.array([[1.0, 0.03], [0.03, 2.6], [0.03, -2.4]]), 0.0, 0.0)
    assert lc.costmap.cost_at(1.0, 0.03) == LETHAL
    assert lc.costmap.cost_at(0.03, 2.6) != LETHAL  # beyond obstacle_max_range 2.5
    assert lc.costmap.cost_at(0.03, -2.4) == LETHAL
    # a max-range reading along +x (nothing hit) clears the old mark
    lc.update(0.0, 0.0, np.zeros((0, 2)), 0.0, 0.0, free_endpoints=np.array([[3.5, 0.03]]))
    assert lc.costmap.cost_at(1.0, 0.03) == FREE_SPACE
    assert lc.costmap.cost_at(0.03, -2.4) == LETHAL  # other bearings untouched


def test_local_costmap_keeps_marks_while_moving_then_drops_them() -> None:
    lc = _free_local()
    lc.update(0.0, 0.0, np.array([[1.0, 0.03]]), 0.0, 0.0)
    lc.update(0.5, 0.0, np.zeros((0, 2)), 0.5, 0.0)
    assert lc.costmap.cost_at(1.0, 0.03) == LETHAL
    lc.update(3.0, 0.0, np.zeros((0, 2)), 3.0, 0.0)
    lc.update(0.0, 0.0, np.zeros((0, 2)), 0.0, 0.0)
    assert lc.costmap.cost_at(1.0, 0.03) == FREE_SPACE


def test_local_costmap_includes_static_walls() -> None:
    gc = GlobalCostmap(_room(), P)
    lc = LocalCostmap(P, gc)
    lc.update(-1.2, 0.0, np.zeros((0, 2)), -1.2, 0.0)
    cm = lc.costmap
    assert cm.cost_at(-1.97, 0.0) == LETHAL
    assert cm.cost_at(-1.97 + 0.12, 0.0) == INSCRIBED
    lc.clear()
    assert lc.costmap.cost_at(-1.97, 0.0) == LETHAL  # clearing never removes the map


def test_local_costmap_inflates_walls_just_outside_window() -> None:
    gc = GlobalCostmap(_room(), P)
    lc = LocalCostmap(P, gc)
    # window from x = -1.82: the west wall's lethal cells (x < -1.88) lie just outside it
    lc.update(-0.29, 0.0, np.zeros((0, 2)), -0.29, 0.0)
    cm = lc.costmap
    assert cm.origin_x == pytest.approx(-1.82)
    assert not (cm.data == LETHAL).any()
    assert cm.data[25, :3].tolist() == [253, 247, 194]  # 0.12, 0.18, 0.24 m from the wall cell


def test_local_costmap_clear_services() -> None:
    lc = _free_local()
    hits = np.array([[0.3, 0.03], [1.2, 0.03], [-1.2, -1.2]])
    lc.update(0.0, 0.0, hits, 0.0, 0.0)
    assert int(lc.obstacles.sum()) == 3
    lc.clear_around(0.0, 0.0, 1.0)
    assert lc.costmap.cost_at(0.3, 0.03) != LETHAL
    assert lc.costmap.cost_at(1.2, 0.03) == LETHAL
    assert lc.costmap.cost_at(-1.2, -1.2) == LETHAL

    lc.update(0.0, 0.0, hits, 0.0, 0.0)
    lc.clear_except_region(0.0, 0.0, 1.0)
    assert lc.costmap.cost_at(0.3, 0.03) == LETHAL
    assert lc.costmap.cost_at(1.2, 0.03) != LETHAL
    assert lc.costmap.cost_at(-1.2, -1.2) != LETHAL

    lc.clear()
    assert int(lc.obstacles.sum()) == 0
    assert int(lc.costmap.data.max()) == FREE_SPACE


def test_local_costmap_rejects_nonfinite_pose_and_ignores_nonfinite_points() -> None:
    lc = _free_local()
    with pytest.raises(ValueError):
        lc.update(float("nan"), 0.0, np.zeros((0, 2)), 0.0, 0.0)
    lc.update(0.0, 0.0, np.array([[np.inf, 0.0], [0.5, np.nan], [0.5, 0.03]]), 0.0, 0.0)
    assert int(lc.obstacles.sum()) == 1


def test_params_from_mapping_validates() -> None:
    p = CostmapParams.from_mapping({"resolution": 0.05, "track_unknown_space": False})
    assert p.resolution == 0.05 and p.track_unknown_space is False
    with pytest.raises(ValueError, match="did you mean 'inflation_radius'"):
        CostmapParams.from_mapping({"inflation_radus": 0.5}, "nav2.yaml")
    with pytest.raises(ValueError):
        CostmapParams(resolution=0.0)
