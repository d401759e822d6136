"""The costmap kernel (tb4.nav._costmapkernel) against the NumPy code it replaced (costmap_reference.py): the same
cells cleared, marked and inflated, bit for bit, on random scans and on edge cases (rays leaving the window and
the map, zero-length rays, NaN and infinite end points, sensors off the window, inflation switched off)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from costmap_reference import ReferenceLocalCostmap  # tests/core/nav on sys.path

from tb4.core.kernels import load_kernel
from tb4.core.maps import OccupancyMap
from tb4.nav.costmap import CostmapParams, GlobalCostmap, inflation_table
from tb4.nav.local_costmap import LocalCostmap

# the NumPy reference casts NaN cells to int64 and divides by zero-length rays, as it always did
pytestmark = [pytest.mark.core, pytest.mark.filterwarnings("ignore::RuntimeWarning")]

kernel = load_kernel("tb4.nav._costmapkernel")


def _random_map(rng: np.random.Generator, resolution: float = 0.05) -> OccupancyMap:
    rows, cols = int(rng.integers(40, 120)), int(rng.integers(40, 120))
    data = np.zeros((rows, cols), dtype=np.int8)
    data[rng.random((rows, cols)) < 0.04] = 100
    for _ in range(int(rng.integers(2, 8))):  # wall segments and blocks
        r, c = int(rng.integers(0, rows)), int(rng.integers(0, cols))
        data[r : r + int(rng.integers(1, 15)), c : c + int(rng.integers(1, 15))] = 100
    data[rng.random((rows, cols)) < 0.03] = -1
    origin = (float(rng.uniform(-3, 3)), float(rng.uniform(-3, 3)))
    return OccupancyMap(data=data, resolution=resolution, origin_x=origin[0], origin_y=origin[1])


def _random_params(rng: np.random.Generator, resolution: float | None = None) -> CostmapParams:
    res = resolution if resolution is not None else float(rng.choice([0.05, 0.06, 0.1, float(rng.uniform(0.02, 0.2))]))
    side = float(rng.uniform(0.5, 4.0))
    return CostmapParams(
        resolution=res,
        robot_radius=float(rng.uniform(0.05, 0.4)),
        inflation_radius=float(rng.choice([0.0, float(rng.uniform(0.0, 0.8))])),
        cost_scaling_factor=float(rng.choice([0.0, float(rng.uniform(0.5, 12.0))])),
        width=side,
        height=float(rng.choice([side, float(rng.uniform(0.5, 4.0))])),
        obstacle_max_range=float(rng.uniform(0.3, 3.0)),
        raytrace_max_range=float(rng.uniform(0.3, 4.0)),
    )


def _scan(rng: np.random.Generator, x: float, y: float) -> tuple[np.ndarray, np.ndarray]:
    """Hits and free end points around (x, y), with the inputs a real scan can carry and a few it should not."""
    n = int(rng.integers(0, 120))
    angles = rng.uniform(-math.pi, math.pi, n)
    ranges = rng.choice([0.0, 1e-12, 0.1, 0.5, 1.5, 2.9, 3.0, 3.2, 5.0, 30.0], n) * rng.uniform(0.8, 1.2, n)
    hits = np.stack([x + ranges * np.cos(angles), y + ranges * np.sin(angles)], axis=1)
    special = rng.random(n)
    hits[special < 0.05] = [x, y]  # zero-length rays
    hits[(special >= 0.05) & (special < 0.08), 0] = np.nan
    hits[(special >= 0.08) & (special < 0.10), 1] = np.inf
    hits[(special >= 0.10) & (special < 0.12)] = [1e300, -1e300]  # finite, but the ray overflows
    hits[(special >= 0.12) & (special < 0.14)] = [x + 1e7, y - 1e7]
    m = int(rng.integers(0, 60))
    a = rng.uniform(-math.pi, math.pi, m)
    free = np.stack([x + 3.0 * np.cos(a), y + 3.0 * np.sin(a)], axis=1)
    return hits, free


def _pair(params: CostmapParams, static: GlobalCostmap | None) -> tuple[LocalCostmap, ReferenceLocalCostmap]:
    return LocalCostmap(params, static), ReferenceLocalCostmap(params, static)


def _assert_same(ours: LocalCostmap, ref: LocalCostmap, what: str) -> None:
    np.testing.assert_array_equal(ours.obstacles, ref.obstacles, err_msg=f"obstacles differ after {what}")
    np.testing.assert_array_equal(ours.costmap.data, ref.costmap.data, err_msg=f"costs differ after {what}")
    assert (ours.costmap.origin_x, ours.costmap.origin_y) == (ref.costmap.origin_x, ref.costmap.origin_y)
    assert ours.costmap.resolution == ref.costmap.resolution


@pytest.mark.parametrize("seed", range(12))
def test_random_scans_give_the_numpy_costmap_bit_for_bit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    grid = _random_map(rng)
    static_params = _random_params(rng)
    static = GlobalCostmap(grid, static_params) if seed % 4 else None
    # the local window on the static grid's resolution (as the simulator runs it) or on another one
    params = _random_params(rng, static_params.resolution if seed % 3 else None)
    ours, ref = _pair(params, static)
    _assert_same(ours, ref, "construction")
    x, y = grid.origin_x + grid.size_x / 2, grid.origin_y + grid.size_y / 2
    for step in range(40):
        x += float(rng.normal(0, 0.3))
        y += float(rng.normal(0, 0.3))
        if step == 25:  # off the map altogether
            x, y = grid.origin_x - 10.0, grid.origin_y + grid.size_y + 10.0
        hits, free = _scan(rng, x, y)
        sensor = (x, y) if rng.random() < 0.8 else (x + float(rng.uniform(-3, 3)), y + float(rng.uniform(-3, 3)))
        with_free = free if rng.random() < 0.8 else None
        ours.update(x, y, hits, *sensor, free_endpoints=with_free)
        ref.update(x, y, hits, *sensor, free_endpoints=with_free)
        _assert_same(ours, ref, f"scan {step}")
        if step % 9 == 8:
            ours.clear_around(x, y, 1.0)
            ref.clear_around(x, y, 1.0)
            _assert_same(ours, ref, "clear_around")


@pytest.mark.parametrize("seed", range(6))
def test_raytrace_clear_edge_rays_match_numpy(seed: int) -> None:
    """The kernel's clearing on end points _finite_points would have dropped (NaN, inf) and on rays that leave the
    window, start off it, have zero length or overflow: called directly, both on the same marks."""
    rng = np.random.default_rng(100 + seed)
    params = _random_params(rng)
    ours, ref = _pair(params, None)
    rows, cols = ours.obstacles.shape
    marks = rng.random((rows, cols)) < 0.5
    ox, oy = ours.costmap.origin_x, ours.costmap.origin_y
    res = params.resolution
    centre = (ox + cols * res / 2, oy + rows * res / 2)
    specials = np.array(
        [
            [np.nan, 0.0],
            [0.0, np.nan],
            [np.inf, 0.0],
            [-np.inf, np.inf],
            [1e300, -1e300],
            [1e-300, 1e-300],
            [centre[0] + 100.0, centre[1]],  # leaves the window
            [ox - 1.0, oy - 1.0],
            [ox, oy],  # the window's corner, on cell boundaries
            [ox + cols * res, oy + rows * res],
        ]
    )
    for sensor in (centre, (ox - 0.5, oy + 0.3), (ox + cols * res + 2.0, oy - 2.0), (ox, oy)):
        ends = np.concatenate([specials, np.array([sensor, [sensor[0] + 1e-10, sensor[1]]])])
        ends = np.concatenate([ends, rng.uniform(-4, 4, (50, 2)) + np.array(centre)])
        for exclude_end in (True, False):
            ours._obstacles[:] = marks
            ref._obstacles[:] = marks
            ours._raytrace_clear(np.ascontiguousarray(ends), *sensor, exclude_end=exclude_end)
            ref._raytrace_clear(ends, *sensor, exclude_end=exclude_end)
            np.testing.assert_array_equal(ours.obstacles, ref.obstacles)
            ours._obstacles[:] = marks
            ref._obstacles[:] = marks
            kernel.mark(*ours._marks_grid(), np.ascontiguousarray(ends), *sensor, params.obstacle_max_range)
            ref.mark(ends, *sensor)
            np.testing.assert_array_equal(ours.obstacles, ref.obstacles)


@pytest.mark.parametrize("exclude_end", [True, False])
@pytest.mark.parametrize("raytrace_max_range", [0.5, 0.52, 1.0, 10.0])
def test_rays_on_exact_cell_boundaries_match_numpy(exclude_end: bool, raytrace_max_range: float) -> None:
    """A power-of-two resolution makes reaches exact multiples of the half-cell step and ends sit on cell
    boundaries: the `t < reach` cut, the clipped-ray rule (0.52: a clipped ray samples its end cell) and the
    window's half-diagonal limit (10 m) all show."""
    params = CostmapParams(resolution=0.0625, width=2.0, height=1.5, raytrace_max_range=raytrace_max_range)
    ours, ref = _pair(params, None)
    ox, oy = ours.costmap.origin_x, ours.costmap.origin_y
    sensor = (ox + 0.5, oy + 0.75)
    step = params.resolution / 2
    directions = ((1, 0), (0, 1), (-1, 0), (0, -1), (1, 1), (-1, 2))
    ends = [[sensor[0] + k * step * dx, sensor[1] + k * step * dy] for k in range(70) for dx, dy in directions]
    ends += [[sensor[0] + raytrace_max_range + d, sensor[1]] for d in (-1e-12, 0.0, 1e-12, 0.01, 0.03)]
    for end in ends:  # one ray at a time, so no other ray clears what this one must leave
        ray = np.array([end], dtype=np.float64)
        for costmap in (ours, ref):
            costmap._obstacles[:] = True
            costmap._raytrace_clear(ray, *sensor, exclude_end=exclude_end)
        np.testing.assert_array_equal(ours.obstacles, ref.obstacles, err_msg=f"ray to {end}")
        for costmap in (ours, ref):
            costmap._obstacles[:] = False
        kernel.mark(*ours._marks_grid(), ray, *sensor, params.obstacle_max_range)
        ref.mark(ray, *sensor)
        np.testing.assert_array_equal(ours.obstacles, ref.obstacles, err_msg=f"mark at {end}")
    params = CostmapParams(resolution=0.0625, obstacle_max_range=0.5)
    ours, ref = _pair(params, None)
    for d in (0.5 - 1e-12, 0.5, 0.5 + 1e-12):  # the marking range's edge
        end = np.array([[sensor[0] + d, sensor[1]]])
        for costmap in (ours, ref):
            costmap._obstacles[:] = False
        kernel.mark(*ours._marks_grid(), end, *sensor, params.obstacle_max_range)
        ref.mark(end, *sensor)
        np.testing.assert_array_equal(ours.obstacles, ref.obstacles)


def test_a_lone_ray_no_longer_than_1e_9_clears_nothing() -> None:
    ours, ref = _pair(CostmapParams(), None)
    sensor = (ours.costmap.origin_x + 1.0, ours.costmap.origin_y + 1.0)
    for length in (0.0, 5e-10, 2e-9):
        for costmap in (ours, ref):
            costmap._obstacles[:] = True
            costmap._raytrace_clear(np.array([[sensor[0] + length, sensor[1]]]), *sensor, exclude_end=False)
        np.testing.assert_array_equal(ours.obstacles, ref.obstacles, err_msg=f"length {length}")
        assert ours.obstacles.all() == (length <= 1e-9)


@pytest.mark.parametrize(
    "inflation_radius, robot_radius, cost_scaling_factor",
    [(0.0, 0.175, 3.0), (0.1, 0.3, 3.0), (0.45, 0.175, 4.0), (0.45, 0.175, 0.0), (1.2, 0.175, 1.0), (0.06, 0.06, 9.0)],
)
@pytest.mark.parametrize("static_resolution", [0.06, 0.05, 0.1, 0.07])
def test_composition_matches_numpy_inflation(
    inflation_radius: float, robot_radius: float, cost_scaling_factor: float, static_resolution: float
) -> None:
    """Walls and marks at the window's edges and corners, dense blocks (interior cells), every inflation regime,
    the static layer on the window's resolution and on others (cell centres sampled across its cells)."""
    rng = np.random.default_rng(7)
    grid = _random_map(rng, resolution=0.05)
    static = GlobalCostmap(grid, CostmapParams(resolution=static_resolution))
    params = CostmapParams(
        resolution=0.06,
        robot_radius=robot_radius,
        inflation_radius=inflation_radius,
        cost_scaling_factor=cost_scaling_factor,
    )
    ours, ref = _pair(params, static)
    for _ in range(20):
        x = grid.origin_x + float(rng.uniform(-1.0, grid.size_x + 1.0))
        y = grid.origin_y + float(rng.uniform(-1.0, grid.size_y + 1.0))
        for costmap in (ours, ref):
            costmap._place_window(x, y)
        marks = rng.random(ours.obstacles.shape) < float(rng.choice([0.0, 0.02, 0.3, 0.9]))
        marks[0, :] = marks[-1, :] = rng.random() < 0.5
        ours._obstacles = marks.copy()
        ref._obstacles = marks.copy()
        ours._compose()
        ref._compose()
        _assert_same(ours, ref, "compose")


def test_inflation_table_is_the_cost_of_each_offset() -> None:
    params = CostmapParams()
    table, k = inflation_table(params.resolution, params)
    assert table.shape == (2 * k + 1, 2 * k + 1) and table.dtype == np.uint8
    assert table[k, k] == 254 and table[0].max() == 0 and table[:, 0].max() == 0  # the rim is past every cost
    assert inflation_table(params.resolution, CostmapParams(inflation_radius=0.0))[1] == -1


def test_kernel_refuses_mismatched_buffers() -> None:
    grid = np.zeros((4, 5), dtype=bool)
    ends = np.zeros((3, 2))
    with pytest.raises(ValueError):
        kernel.raytrace_clear(grid, 5, 5, 0.0, 0.0, 0.1, ends, 0.0, 0.0, 1.0, 1.0, 0)
    with pytest.raises(ValueError):
        kernel.raytrace_clear(grid, 4, 5, 0.0, 0.0, 0.1, np.zeros(3), 0.0, 0.0, 1.0, 1.0, 0)
    with pytest.raises(ValueError):
        kernel.raytrace_clear(grid, 4, 5, 0.0, 0.0, 0.1, ends, 0.0, 0.0, 1.0, 1.0, 3)
    with pytest.raises(ValueError):
        kernel.mark(grid, 4, 5, 0.0, 0.0, 0.0, ends, 0.0, 0.0, 1.0)
    with pytest.raises(ValueError):
        kernel.compose(np.zeros(20, np.uint8), 4, 5, 0.0, 0.0, 0.1, grid, b"", 0, 0, 0.0, 0.0, 1.0, 1, b"", 2)
    with pytest.raises(TypeError):  # a read-only grid
        kernel.mark(b"\0" * 20, 4, 5, 0.0, 0.0, 0.1, ends, 0.0, 0.0, 1.0)
