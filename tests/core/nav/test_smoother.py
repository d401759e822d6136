"""Path smoothing (Nav2 simple smoother semantics) and IsPathValid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.nav.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap2D
from tb4.nav.smoother import is_path_valid, smooth_path

pytestmark = pytest.mark.core

RES = 0.06


def _curvature(xy: np.ndarray) -> float:
    return float((np.diff(xy, n=2, axis=0) ** 2).sum())


def _zigzag(n: int = 60) -> np.ndarray:
    x = np.arange(n) * RES
    y = np.where(np.arange(n) % 2 == 0, 0.0, RES)
    return np.stack([x, y, np.zeros(n)], axis=1)


def test_smoothing_keeps_endpoints_and_reduces_curvature() -> None:
    path = _zigzag()
    path[0, 2], path[-1, 2] = 0.3, -0.4
    result = smooth_path(path)
    assert result.was_completed
    assert not result.in_collision
    out = result.path
    assert out.shape == path.shape
    assert np.array_equal(out[0], path[0]) and np.array_equal(out[-1], path[-1])
    assert _curvature(out[:, :2]) < 0.2 * _curvature(path[:, :2])
    # stays close to the original (data term)
    assert np.abs(out[:, 1] - path[:, 1]).max() < RES
    # yaw recomputed along the path: close to 0 for a path running along +x
    assert np.abs(out[1:-1, 2]).max() < 0.3
    assert 1 < result.iterations < 1000


def test_smoothing_input_is_not_modified_and_2d_input_gets_yaw() -> None:
    path = _zigzag()[:, :2].copy()
    before = path.copy()
    out = smooth_path(path).path
    assert np.array_equal(path, before)
    assert out.shape == (len(path), 3)
    diag = np.stack([np.arange(10) * 0.1, np.arange(10) * 0.1], axis=1)
    assert np.allclose(smooth_path(diag).path[:, 2], math.pi / 4)


def _corner_costmap() -> Costmap2D:
    """Inscribed cells filling the inside of the corner of the L-shaped path (0,0) -> (1.35,0) -> (1.35,2),
    up to the path's own cells, plus a lethal block further in."""
    data = np.zeros((60, 60), dtype=np.uint8)
    data[9:13, 26:30] = INSCRIBED  # x 1.06..1.30, y 0.04..0.28 (the path runs along y ~ 0 and x = 1.35)
    data[14:18, 20:24] = LETHAL  # x 0.70..0.94, y 0.34..0.58
    return Costmap2D(data, RES, -0.5, -0.5)


def _l_path() -> np.ndarray:
    leg1 = np.stack([np.linspace(0.0, 1.35, 46), np.zeros(46)], axis=1)
    leg2 = np.stack([np.full(46, 1.35), np.linspace(0.0, 2.0, 46)], axis=1)
    return np.vstack([leg1, leg2[1:]])


def test_smoothing_never_moves_points_into_obstacles() -> None:
    cm = _corner_costmap()
    path = _l_path()
    assert (cm.costs_at(path) < INSCRIBED).all()
    free_run = smooth_path(path, w_data=0.05, w_smooth=0.45).path
    assert (cm.costs_at(free_run) >= INSCRIBED).any(), "without a costmap the corner gets cut"
    guarded = smooth_path(path, cm, w_data=0.05, w_smooth=0.45, check_for_collision=True)
    assert (cm.costs_at(guarded.path) < INSCRIBED).all()
    assert not guarded.in_collision
    assert _curvature(guarded.path[:, :2]) < _curvature(path)


def test_in_collision_reported_when_checked() -> None:
    cm = _corner_costmap()
    through = np.stack([np.linspace(0.5, 2.5, 30), np.full(30, 0.45)], axis=1)  # crosses the block
    assert smooth_path(through, cm, check_for_collision=True).in_collision
    assert not smooth_path(through, cm, check_for_collision=False).in_collision


def test_was_completed_false_when_time_or_iterations_run_out() -> None:
    path = _zigzag(400)
    timed_out = smooth_path(path, max_duration=0.0)
    assert not timed_out.was_completed
    assert timed_out.iterations == 1
    capped = smooth_path(path, max_iterations=3)
    assert not capped.was_completed and capped.iterations == 3
    assert smooth_path(path[:2]).was_completed  # nothing to smooth


def test_smoother_rejects_bad_input() -> None:
    with pytest.raises(ValueError):
        smooth_path(np.zeros((5, 4)))
    with pytest.raises(ValueError):
        smooth_path(np.array([[0.0, 0.0], [np.nan, 1.0], [2.0, 2.0]]))
    with pytest.raises(ValueError):
        smooth_path(_zigzag(), w_smooth=0.6)


def _validity_map() -> Costmap2D:
    data = np.zeros((10, 10), dtype=np.uint8)
    data[5, 5] = LETHAL
    data[5, 6] = INSCRIBED
    data[5, 7] = NO_INFORMATION
    return Costmap2D(data, 0.1, 0.0, 0.0)


def test_is_path_valid_nav2_semantics() -> None:
    cm = _validity_map()
    clean = np.array([[0.05, 0.05, 0.0], [0.25, 0.05, 0.0], [0.95, 0.95, 0.0]])
    assert is_path_valid(cm, clean) == (True, [])
    path = np.array([[0.05, 0.05], [0.55, 0.55], [0.65, 0.55], [0.75, 0.55], [1.5, 0.5]])
    assert is_path_valid(cm, path) == (False, [1, 4])  # lethal and off the map
    assert is_path_valid(cm, path, max_cost=253) == (False, [1, 2, 4])
    assert is_path_valid(cm, path, consider_unknown_as_obstacle=True) == (False, [1, 3, 4])
    assert is_path_valid(cm, np.zeros((0, 3))) == (True, [])
    assert is_path_valid(cm, np.array([[np.nan, 0.1]])) == (False, [0])
