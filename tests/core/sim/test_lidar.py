"""Lidar ranges against analytic distances: walls (axis-aligned and angled), circles, range limits, noise."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import default_robot_params
from tb4.sim.collision import DistanceField
from tb4.sim.lidar import Lidar, ray_circle_ranges

pytestmark = pytest.mark.core

RES = 0.03
PARAMS = default_robot_params().lidar


def room(width_m: float, height_m: float, wall_cells: int = 3) -> OccupancyMap:
    """Free rectangle with walls `wall_cells` thick, origin at (0, 0)."""
    h, w = round(height_m / RES), round(width_m / RES)
    data = np.zeros((h, w), dtype=np.int8)
    k = wall_cells
    data[:k, :] = data[-k:, :] = 100
    data[:, :k] = data[:, -k:] = 100
    return OccupancyMap(data, RES, 0.0, 0.0)


def lidar_for(grid: OccupancyMap, **changes: float) -> Lidar:
    params = dataclasses.replace(PARAMS, **changes) if changes else PARAMS
    return Lidar(params, DistanceField.from_mask(grid), 0)


def beam_angles(n: int = PARAMS.beams) -> np.ndarray:
    return np.arange(n) * 2 * math.pi / n


def box_distances(x: float, y: float, yaw: float, lo: tuple[float, float], hi: tuple[float, float]) -> np.ndarray:
    """Analytic distance from (x, y) to the inside of the box [lo, hi] along each beam."""
    a = yaw + beam_angles()
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 1e-12, (hi[0] - x) / c, np.where(c < -1e-12, (lo[0] - x) / c, np.inf))
        ty = np.where(s > 1e-12, (hi[1] - y) / s, np.where(s < -1e-12, (lo[1] - y) / s, np.inf))
    return np.minimum(tx, ty)


@pytest.mark.parametrize(("x", "y", "yaw"), [(2.0, 1.5, 0.0), (4.1, 2.7, 1.0), (0.5, 0.4, -2.5)])
def test_axis_aligned_room_matches_analytic_ranges(x: float, y: float, yaw: float) -> None:
    grid = room(6.0, 3.6)
    k = 3 * RES
    expected = box_distances(x, y, yaw, (k, k), (6.0 - k, 3.6 - k))
    scan = lidar_for(grid).scan(x, y, yaw, time=1.5)
    assert scan.ranges.dtype == np.float32 and scan.ranges.shape == (360,)
    assert np.all(np.isfinite(scan.ranges))
    assert np.max(np.abs(scan.ranges - expected)) < RES  # within a cell
    assert scan.time == 1.5
    assert (scan.angle_min, scan.angle_increment) == (0.0, pytest.approx(2 * math.pi / 360))
    assert scan.angle_max == pytest.approx(2 * math.pi * 359 / 360)


def test_beam_zero_is_the_robot_heading() -> None:
    grid = room(6.0, 3.6)
    lidar = lidar_for(grid)
    facing_north = lidar.ranges(2.0, 1.5, math.pi / 2)
    assert facing_north[0] == pytest.approx(3.6 - 3 * RES - 1.5, abs=RES)  # beam 0 along +y
    assert facing_north[90] == pytest.approx(2.0 - 3 * RES, abs=RES)  # beam 90 (left) along -x


@pytest.mark.parametrize("tilt_deg", [20.0, 37.0])
def test_angled_walls_match_analytic_ranges(tilt_deg: float) -> None:
    """A square room rotated by tilt: compare beams that meet a wall at most 60 degrees off its normal."""
    tilt = math.radians(tilt_deg)
    n = 260
    cx = cy = n * RES / 2
    half = 2.4
    cols, rows = np.meshgrid((np.arange(n) + 0.5) * RES - cx, (np.arange(n) + 0.5) * RES - cy)
    u = np.cos(tilt) * cols + np.sin(tilt) * rows
    v = -np.sin(tilt) * cols + np.cos(tilt) * rows
    data = np.where((np.abs(u) < half) & (np.abs(v) < half), 0, 100).astype(np.int8)
    grid = OccupancyMap(data, RES, 0.0, 0.0)
    px, py, yaw = cx + 0.3, cy - 0.5, 0.4
    ranges = lidar_for(grid).ranges(px, py, yaw)
    a = yaw + beam_angles() - tilt  # beams in the room frame
    pu = math.cos(tilt) * (px - cx) + math.sin(tilt) * (py - cy)
    pv = -math.sin(tilt) * (px - cx) + math.cos(tilt) * (py - cy)
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore"):
        tu = np.where(c > 0, (half - pu) / c, (-half - pu) / c)
        tv = np.where(s > 0, (half - pv) / s, (-half - pv) / s)
    expected = np.minimum(tu, tv)
    incidence = np.where(tu < tv, np.abs(c), np.abs(s))  # cosine of the angle to the wall normal
    ok = incidence > 0.5
    assert ok.sum() > 200
    assert np.max(np.abs(ranges[ok] - expected[ok])) < 2.0 * RES  # staircase walls: within ~a cell or two
    assert np.median(np.abs(ranges - expected)) < RES


def test_circle_obstacle_matches_analytic_intersection() -> None:
    grid = room(12.0, 12.0)
    lidar = lidar_for(grid)
    x, y, yaw = 3.0, 6.0, 0.3
    circle = (5.0, 6.5, 0.4)
    ranges = lidar.ranges(x, y, yaw, [circle])
    a = yaw + beam_angles()
    dx, dy = circle[0] - x, circle[1] - y
    b = dx * np.cos(a) + dy * np.sin(a)
    disc = b * b - (dx * dx + dy * dy - circle[2] ** 2)
    with np.errstate(invalid="ignore"):
        near = b - np.sqrt(disc)
    hits = (disc >= 0) & (near > 0)  # the circle is in front of the beam
    expected = near[hits]
    assert hits.sum() >= 20
    np.testing.assert_allclose(ranges[hits], expected, atol=1e-9)
    assert np.all(ranges[~hits] > 2.5)  # the other beams reach the walls


def test_ray_circle_inside_and_behind() -> None:
    c, s = np.array([1.0, -1.0]), np.array([0.0, 0.0])
    assert ray_circle_ranges(0.0, 0.0, c, s, [(0.0, 0.0, 0.5)]).tolist() == [0.0, 0.0]  # sensor inside
    out = ray_circle_ranges(0.0, 0.0, c, s, [(2.0, 0.0, 0.5)])
    assert out[0] == pytest.approx(1.5) and out[1] == math.inf  # circle behind beam 1
    assert np.all(np.isinf(ray_circle_ranges(0.0, 0.0, c, s, [])))


def test_beyond_range_max_is_inf() -> None:
    grid = room(30.0, 4.0)
    lidar = lidar_for(grid)
    ranges = lidar.ranges(2.0, 2.0, 0.0)
    assert ranges[0] == math.inf  # 27.9 m of corridor ahead
    assert ranges[180] == pytest.approx(2.0 - 3 * RES, abs=RES)
    short = lidar_for(grid, range_max=1.5).ranges(2.0, 2.0, 0.0)
    assert short[90] == math.inf and short[180] == math.inf  # 1.91 m > 1.5 m
    assert np.isfinite(lidar.ranges(2.0, 2.0, 0.0)[90])


def test_circles_at_the_range_limit() -> None:
    """Circles wholly beyond range_max are left out before intersecting (most scans meet none); one whose centre
    is beyond it but whose near face is within it is still seen."""
    grid = room(30.0, 4.0)
    lidar = lidar_for(grid)
    rmax = lidar.params.range_max
    straddling = (2.0 + rmax + 0.2, 2.0, 0.4)  # centre 0.2 m beyond range_max, face 0.2 m within it
    ranges = lidar.ranges(2.0, 2.0, 0.0, [straddling])
    assert ranges[0] == pytest.approx(rmax - 0.2, abs=1e-9)
    beyond = (2.0 + rmax + 0.5, 2.0, 0.4)  # face 0.1 m beyond it
    assert lidar.ranges(2.0, 2.0, 0.0, [beyond])[0] == math.inf
    both = lidar.ranges(2.0, 2.0, 0.0, np.array([beyond, straddling]))  # a fleet's peers come as an array
    np.testing.assert_array_equal(both, ranges)


def test_circles_that_are_not_finite_or_have_no_size_are_left_out() -> None:
    """Peers' poses come over DDS: a NaN or infinite circle, or one of radius 0 or less, is nothing a beam meets
    (no NaN range, no exception in the simulator loop), and the walls still read as without it."""
    grid = room(12.0, 12.0)
    lidar = lidar_for(grid)
    walls = lidar.ranges(3.0, 6.0, 0.0)
    for bad in [
        (math.nan, 6.0, 0.4),
        (5.0, math.inf, 0.4),
        (5.0, 6.0, math.nan),
        (5.0, 6.0, math.inf),
        (5.0, 6.0, 0.0),
        (5.0, 6.0, -1.0),
        (3.0, 6.0, 0.0),
    ]:
        np.testing.assert_array_equal(lidar.ranges(3.0, 6.0, 0.0, [bad]), walls, err_msg=str(bad))
    assert np.all(ray_circle_ranges(3.0, 6.0, np.array([1.0]), np.array([0.0]), [(math.nan, 0.0, 1.0)]) == math.inf)


def test_closer_than_range_min_is_inf() -> None:
    grid = room(6.0, 6.0)
    lidar = lidar_for(grid)
    ranges = lidar.ranges(3.0, 3.0, 0.0, [(3.2, 3.0, 0.1)])  # circle face 0.1 m ahead
    assert ranges[0] == math.inf
    assert ranges[180] == pytest.approx(3.0 - 3 * RES, abs=RES)
    assert lidar.ranges(3.0, 3.0, 0.0, [(3.4, 3.0, 0.1)])[0] == pytest.approx(0.3)


def test_beams_leaving_the_map_see_nothing() -> None:
    grid = OccupancyMap(np.zeros((100, 100), dtype=np.int8), RES, 0.0, 0.0)
    assert np.all(np.isinf(lidar_for(grid).ranges(1.5, 1.5, 0.0)))
    assert np.all(np.isinf(lidar_for(grid).ranges(-5.0, 1.5, 0.0)))  # sensor off the map


def test_noise_is_seeded_and_sized() -> None:
    grid = room(6.0, 6.0)
    clean = lidar_for(grid).scan(3.0, 3.0, 0.0, 0.0).ranges
    # range noise alone (dropouts are tested in test_sensor_noise.py)
    noisy1 = lidar_for(grid, dropout_probability=0.0).scan(3.0, 3.0, 0.0, 0.0, noise=True).ranges
    noisy2 = lidar_for(grid, dropout_probability=0.0).scan(3.0, 3.0, 0.0, 0.0, noise=True).ranges
    np.testing.assert_array_equal(noisy1, noisy2)
    err = noisy1.astype(np.float64) - clean
    assert 0.5 * PARAMS.noise_stddev < np.std(err) < 1.5 * PARAMS.noise_stddev
    np.testing.assert_array_equal(clean, lidar_for(grid).scan(3.0, 3.0, 0.0, 0.0).ranges)


def test_configurable_beam_count() -> None:
    grid = room(6.0, 6.0)
    lidar = lidar_for(grid, beams=720)
    scan = lidar.scan(3.0, 3.0, 0.0, 0.0)
    assert scan.ranges.shape == (720,)
    assert scan.angle_increment == pytest.approx(math.pi / 360)
    assert scan.ranges[360] == pytest.approx(3.0 - 3 * RES, abs=RES)


def test_open_map_edge_and_kernel_input_checks() -> None:
    """A map without walls: beams that leave it see nothing; the C kernel refuses mismatched buffers."""
    from tb4.sim import _raymarch  # type: ignore[attr-defined]

    grid = OccupancyMap(np.zeros((40, 40), dtype=np.int8), RES, 0.0, 0.0)
    lidar = lidar_for(grid)
    assert np.all(np.isinf(lidar.ranges(0.6, 0.6, 0.0)))
    table = lidar._table
    out = np.empty(4)
    settings = (64, 48, 2048, 256, 2)
    with pytest.raises(ValueError):
        _raymarch.march(
            table,
            table.shape[1] + 1,
            table.shape[0],
            1.0,
            1.0,
            np.ones(4),
            np.zeros(4),
            10.0,
            (0, 0, 1, 1),
            settings,
            out,
        )
    with pytest.raises(ValueError):
        _raymarch.march(
            table, table.shape[1], table.shape[0], 1.0, 1.0, np.ones(3), np.zeros(4), 10.0, (0, 0, 1, 1), settings, out
        )
