"""The global obstacle layer on the costmap kernel (tb4.nav._costmapkernel) against the NumPy code it replaced
(obstacle_reference.py): the same marks cleared and set and the same costs re-inflated, bit for bit, on random
scans and on edge cases (rays leaving the map, zero-length rays, NaN and infinite end points, sensors off the map,
unknown cells, every inflation regime, range edges on exact cell boundaries)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from obstacle_reference import ReferenceGlobalObstacleLayer  # tests/core/nav on sys.path

from tb4.core.maps import OccupancyMap
from tb4.nav.costmap import CostmapParams, GlobalCostmap, inflation_table, stamping_is_exact
from tb4.nav.obstacle_layer import GlobalObstacleLayer

# the NumPy reference casts NaN cells to int64 and divides by zero-length rays, as it always did
pytestmark = [pytest.mark.core, pytest.mark.filterwarnings("ignore::RuntimeWarning")]


def _random_map(rng: np.random.Generator) -> OccupancyMap:
    rows, cols = int(rng.integers(30, 110)), int(rng.integers(30, 110))
    data = np.zeros((rows, cols), dtype=np.int8)
    data[rng.random((rows, cols)) < 0.03] = 100
    for _ in range(int(rng.integers(2, 8))):  # wall segments and blocks
        r, c = int(rng.integers(0, rows)), int(rng.integers(0, cols))
        data[r : r + int(rng.integers(1, 15)), c : c + int(rng.integers(1, 15))] = 100
    for _ in range(int(rng.integers(0, 4))):  # unknown patches, and scattered unknown cells
        r, c = int(rng.integers(0, rows)), int(rng.integers(0, cols))
        data[r : r + int(rng.integers(1, 20)), c : c + int(rng.integers(1, 20))] = -1
    data[rng.random((rows, cols)) < 0.03] = -1
    resolution = float(rng.choice([0.05, 0.06, 0.1]))
    origin = (float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)))
    return OccupancyMap(data=data, resolution=resolution, origin_x=origin[0], origin_y=origin[1])


def _random_params(rng: np.random.Generator) -> CostmapParams:
    return CostmapParams(
        resolution=float(rng.choice([0.05, 0.06, 0.1, float(rng.uniform(0.03, 0.2))])),
        robot_radius=float(rng.uniform(0.05, 0.4)),
        inflation_radius=float(rng.choice([0.0, float(rng.uniform(0.0, 0.8))])),
        cost_scaling_factor=float(rng.choice([0.0, float(rng.uniform(0.5, 12.0))])),
        obstacle_max_range=float(rng.uniform(0.3, 3.0)),
        raytrace_max_range=float(rng.uniform(0.3, 4.0)),
        track_unknown_space=bool(rng.random() < 0.7),
        obstacle_layer=True,
    )


def _pair(grid: OccupancyMap, params: CostmapParams) -> tuple[GlobalObstacleLayer, ReferenceGlobalObstacleLayer]:
    costmap = GlobalCostmap(grid, params)
    ours = costmap.obstacles
    assert isinstance(ours, GlobalObstacleLayer)
    ref = ReferenceGlobalObstacleLayer(costmap.static, costmap._inflated, params)
    return ours, ref


def _scan(rng: np.random.Generator, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
    """Hits and free end points around (x, y), with the inputs a real scan can carry and a few it should not."""
    n = int(rng.integers(0, 150))
    angles = rng.uniform(-math.pi, math.pi, n)
    ranges = rng.choice([0.0, 1e-12, 0.02, 0.1, 0.5, 1.5, 2.9, 3.0, 3.2, 5.0, 30.0], n) * rng.uniform(0.8, 1.2, n)
    hits = np.stack([x + ranges * np.cos(angles), y + ranges * np.sin(angles)], axis=1)
    special = rng.random(n)
    hits[special < 0.05] = [x, y]  # zero-length rays
    hits[(special >= 0.05) & (special < 0.08), 0] = np.nan
    hits[(special >= 0.08) & (special < 0.10), 1] = np.inf
    hits[(special >= 0.10) & (special < 0.12)] = [1e300, -1e300]  # finite, but the ray overflows
    hits[(special >= 0.12) & (special < 0.14)] = [x + 1e7, y - 1e7]
    m = int(rng.integers(0, 60))
    a = rng.uniform(-math.pi, math.pi, m)
    free = np.stack([x + 3.5 * np.cos(a), y + 3.5 * np.sin(a)], axis=1)
    free[rng.random(m) < 0.05] = [x, y]
    return hits, free


def _assert_same(ours: GlobalObstacleLayer, ref: GlobalObstacleLayer, what: str) -> None:
    np.testing.assert_array_equal(ours.marks, ref.marks, err_msg=f"marks differ after {what}")
    np.testing.assert_array_equal(ours.costmap.data, ref.costmap.data, err_msg=f"costs differ after {what}")


@pytest.mark.parametrize("seed", range(16))
def test_random_scans_give_the_numpy_layer_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    grid = _random_map(rng)
    params = _random_params(rng)
    ours, ref = _pair(grid, params)
    _assert_same(ours, ref, "construction")
    x, y = grid.origin_x + grid.size_x / 2, grid.origin_y + grid.size_y / 2
    for step in range(40):
        x += float(rng.normal(0, 0.4))
        y += float(rng.normal(0, 0.4))
        if step == 20:  # off the map altogether, then near a corner
            x, y = grid.origin_x - 10.0, grid.origin_y + grid.size_y + 10.0
        if step == 21:
            x, y = grid.origin_x + 0.01, grid.origin_y + 0.01
        if step == 30:  # a sensor so far off that its cell overflows int64
            x, y = 1e300, -1e300
        hits, free = _scan(rng, x, y)
        free_ends = free if rng.random() < 0.8 else np.zeros((0, 2))
        ours.update(x, y, hits, free_ends)
        ref.update(x, y, hits, free_ends)
        _assert_same(ours, ref, f"scan {step}")
        if step % 9 == 8:
            ours.clear_around(x, y, 1.0)
            ref.clear_around(x, y, 1.0)
            _assert_same(ours, ref, "clear_around")
        if step % 13 == 12:
            ours.clear_except_region(x, y, 2.0)
            ref.clear_except_region(x, y, 2.0)
            _assert_same(ours, ref, "clear_except_region")


@pytest.mark.parametrize("seed", range(6))
def test_clearing_and_marking_edge_rays_match_numpy(seed: int) -> None:
    """The kernel's clearing and marking on end points _finite would have dropped (NaN, inf) and on rays that
    leave the map, start off it, have zero length or overflow: called directly, both on the same marks."""
    rng = np.random.default_rng(100 + seed)
    grid = _random_map(rng)
    params = _random_params(rng)
    ours, ref = _pair(grid, params)
    s = ours.static
    ox, oy, res = s.origin_x, s.origin_y, s.resolution
    marks = rng.random(ours.marks.shape) < 0.5
    centre = (ox + s.cols * res / 2, oy + s.rows * res / 2)
    specials = np.array(
        [
            [np.nan, 0.0],
            [0.0, np.nan],
            [np.inf, 0.0],
            [-np.inf, np.inf],
            [1e300, -1e300],
            [1e-300, 1e-300],
            [centre[0] + 100.0, centre[1]],  # leaves the map
            [ox - 1.0, oy - 1.0],
            [ox, oy],  # the map's corner, on cell boundaries
            [ox + s.cols * res, oy + s.rows * res],
        ]
    )
    far = (ox + s.cols * res + 2.0, oy - 2.0)
    for sensor in (centre, (ox - 0.5, oy + 0.3), far, (ox, oy), (1.7e308, -1.7e308)):
        ends = np.concatenate([specials, np.array([sensor, [sensor[0] + 1e-10, sensor[1]]])])
        ends = np.ascontiguousarray(np.concatenate([ends, rng.uniform(-4, 4, (50, 2)) + np.array(centre)]))
        for hits, free in ((ends, ends[:0]), (ends[:0], ends), (ends[::2].copy(), ends[1::2].copy())):
            ours.marks[:] = marks
            ref.marks[:] = marks
            ours.clear_rays(*sensor, hits, free)
            ref.clear_rays(*sensor, hits, free)
            np.testing.assert_array_equal(ours.marks, ref.marks)
            ours.marks[:] = marks & (rng.random(marks.shape) < 0.5)
            ref.marks[:] = ours.marks
            ours.mark_hits(*sensor, hits)
            ref.mark_hits(*sensor, hits)
            np.testing.assert_array_equal(ours.marks, ref.marks)


@pytest.mark.parametrize("raytrace_max_range", [0.5, 0.53125, 1.0, 10.0])
@pytest.mark.parametrize("obstacle_max_range", [0.5, 2.0])
def test_rays_on_exact_cell_boundaries_match_numpy(raytrace_max_range: float, obstacle_max_range: float) -> None:
    """A power-of-two resolution makes reaches exact multiples of the half-cell step and ends sit on cell
    boundaries: the `t < reach` cut, the half-cell stop of hits, hits exactly at and just past
    raytrace_max_range (clipped, no stop short) and at obstacle_max_range all show."""
    data = np.zeros((48, 64), dtype=np.int8)
    data[0, :] = 100
    data[10:14, 40] = -1
    grid = OccupancyMap(data=data, resolution=0.0625, origin_x=-1.0, origin_y=-0.5)
    params = CostmapParams(
        resolution=0.0625,
        obstacle_max_range=obstacle_max_range,
        raytrace_max_range=raytrace_max_range,
        obstacle_layer=True,
    )
    ours, ref = _pair(grid, params)
    sensor = (0.5, 0.75)
    step = params.resolution / 2
    directions = ((1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 2))
    ends = [[sensor[0] + k * step * dx, sensor[1] + k * step * dy] for k in range(70) for dx, dy in directions]
    for edge in (raytrace_max_range, obstacle_max_range, 0.5 * step, step):
        ends += [[sensor[0] + edge + d, sensor[1]] for d in (-1e-12, 0.0, 1e-12, 0.01, 0.03)]
    for end in ends:  # one ray at a time, so no other ray clears what this one must leave
        ray = np.array([end], dtype=np.float64)
        for layer in (ours, ref):
            layer.marks[:] = True
            layer.clear_rays(*sensor, ray, ray[:0])
        np.testing.assert_array_equal(ours.marks, ref.marks, err_msg=f"hit at {end}")
        for layer in (ours, ref):
            layer.marks[:] = True
            layer.clear_rays(*sensor, ray[:0], ray)
        np.testing.assert_array_equal(ours.marks, ref.marks, err_msg=f"free end at {end}")
        for layer in (ours, ref):
            layer.marks[:] = False
            layer.mark_hits(*sensor, ray)
        np.testing.assert_array_equal(ours.marks, ref.marks, err_msg=f"mark at {end}")
        ours.update(*sensor, ray, ray[:0])
        ref.update(*sensor, ray, ray[:0])
        _assert_same(ours, ref, f"update with {end}")


@pytest.mark.parametrize(
    "inflation_radius, robot_radius, cost_scaling_factor",
    [(0.0, 0.175, 3.0), (0.1, 0.3, 3.0), (0.45, 0.175, 4.0), (0.45, 0.175, 0.0), (1.2, 0.175, 1.0), (0.06, 0.06, 9.0)],
)
@pytest.mark.parametrize("resolution", [0.06, 0.05, 0.1])
@pytest.mark.parametrize("track_unknown_space", [True, False])
def test_reinflation_matches_the_distance_transform(
    inflation_radius: float,
    robot_radius: float,
    cost_scaling_factor: float,
    resolution: float,
    track_unknown_space: bool,
) -> None:
    """Marks dense and sparse, next to unknown cells and walls, at the map's edges; regions clipped by the map
    and lying off it; every inflation regime, with and without unknown space."""
    rng = np.random.default_rng(7)
    grid = _random_map(rng)
    params = CostmapParams(
        resolution=resolution,
        robot_radius=robot_radius,
        inflation_radius=inflation_radius,
        cost_scaling_factor=cost_scaling_factor,
        track_unknown_space=track_unknown_space,
        obstacle_layer=True,
    )
    ours, ref = _pair(grid, params)
    assert ours._stamp
    rows, cols = ours.marks.shape
    for _ in range(25):
        marks = rng.random((rows, cols)) < float(rng.choice([0.0, 0.01, 0.1, 0.5, 0.95]))
        marks[0, :] = marks[-1, :] = rng.random() < 0.5
        marks[:, 0] = rng.random() < 0.5
        ours.marks[:] = marks
        ref.marks[:] = marks
        r0, c0 = int(rng.integers(-30, rows + 30)), int(rng.integers(-30, cols + 30))
        r1, c1 = r0 + int(rng.integers(0, 40)), c0 + int(rng.integers(0, 40))
        ours._recompose(r0, r1, c0, c1)
        ref._recompose(r0, r1, c0, c1)
        _assert_same(ours, ref, f"re-inflating rows {r0}..{r1}, cols {c0}..{c1}")
        ours._recompose(-5, rows + 5, -5, cols + 5)  # the whole map
        ref._recompose(-5, rows + 5, -5, cols + 5)
        _assert_same(ours, ref, "re-inflating the whole map")


def test_the_distance_transform_path_when_stamping_is_not_exact() -> None:
    """A table whose equal-distance offsets disagree, or whose cost rises with distance, is refused, and the
    layer then re-inflates with inflate(), still matching the reference."""
    params = CostmapParams(obstacle_layer=True)
    table, k = inflation_table(params.resolution, params)
    assert stamping_is_exact(table, k) and stamping_is_exact(np.zeros(0, np.uint8), -1)
    tie = table.copy()
    tie[k + 3, k + 4] = tie[k + 5, k] + 1  # (3, 4) and (5, 0) are both 5 cells away
    assert not stamping_is_exact(tie, k)
    rising = table.copy()
    rising[k, k + k] = 200
    assert not stamping_is_exact(rising, k)
    rng = np.random.default_rng(3)
    grid = _random_map(rng)
    ours, ref = _pair(grid, params)
    ours._stamp = False
    for _ in range(10):
        x = grid.origin_x + float(rng.uniform(0, grid.size_x))
        y = grid.origin_y + float(rng.uniform(0, grid.size_y))
        hits, free = _scan(rng, x, y)
        ours.update(x, y, hits, free)
        ref.update(x, y, hits, free)
        _assert_same(ours, ref, "scan")


def test_kernel_reinflate_refuses_bad_boxes() -> None:
    kernel = GlobalCostmap(OccupancyMap(np.zeros((8, 8), np.int8), 0.06), CostmapParams(obstacle_layer=True))
    layer = kernel.obstacles
    assert isinstance(layer, GlobalObstacleLayer)
    k = layer._kernel
    static, marks = layer.static.data, layer.marks
    table, tk = layer._table, layer._table_k
    out = np.zeros((2, 2), np.uint8)
    k.reinflate(out, static, marks, 8, 8, 0, 8, 0, 8, 3, 5, 3, 5, table, tk)
    for bad in ((0, 8, 0, 8, 3, 5, 3, 6), (0, 9, 0, 8, 3, 5, 3, 5), (4, 8, 0, 8, 3, 5, 3, 5), (0, 8, 0, 8, 5, 3, 3, 5)):
        with pytest.raises(ValueError):
            k.reinflate(out, static, marks, 8, 8, *bad, table, tk)
    with pytest.raises(ValueError):
        k.reinflate(out, static, marks[:4], 8, 8, 0, 8, 0, 8, 3, 5, 3, 5, table, tk)
    with pytest.raises(ValueError):
        k.reinflate(out, static, marks, 8, 8, 0, 8, 0, 8, 3, 5, 3, 5, table[:-1], tk)
