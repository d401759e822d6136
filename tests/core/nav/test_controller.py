"""Regulated Pure Pursuit, goal checker and progress checker, driven against the real Simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.nav.controller import (
    LETHAL_COST,
    GoalChecker,
    ProgressChecker,
    RegulatedPurePursuit,
    arc_poses,
    costs_at,
    footprint_in_collision,
)
from tb4.nav.costmap import Costmap2D
from tb4.nav.follow_path import make_controller, make_goal_checker
from tb4.nav.params import load_nav2_params

pytestmark = pytest.mark.core

PARAMS = load_nav2_params()
DT = PARAMS.controller_period


def _drive(kit, path: np.ndarray, start, max_time: float = 40.0):
    """Follow `path` with RPP on the simulated robot until the goal checker is satisfied."""
    h = kit.Harness(kit.box_map(8.0, 8.0), start)
    ctl = make_controller(PARAMS)
    ctl.set_plan(path)
    checker = make_goal_checker(PARAMS)
    cmds = []
    reached = False
    while h.sim.time < max_time:
        pose = h.pose
        if checker.is_goal_reached(pose, ctl.goal):
            reached = True
            break
        res = ctl.compute_velocity(pose, None, DT)
        cmds.append((res.v, res.w))
        h.sim.set_velocity_command(res.v, res.w)
        h.sim.step(1)
    return h, reached, np.array(cmds)


def _straight(x0, y0, x1, y1, yaw_end):
    n = 50
    xs, ys = np.linspace(x0, x1, n), np.linspace(y0, y1, n)
    yaw = np.full(n, math.atan2(y1 - y0, x1 - x0))
    yaw[-1] = yaw_end
    return np.stack([xs, ys, yaw], axis=1)


def test_straight_path_reaches_goal_within_tolerance_and_limits(kit):
    path = _straight(1.0, 1.0, 5.0, 1.0, math.pi / 2)
    h, reached, cmds = _drive(kit, path, (1.0, 1.0, 0.0))
    assert reached
    x, y, yaw = h.pose
    assert math.hypot(x - 5.0, y - 1.0) <= 0.25
    assert kit.yaw_error(yaw, math.pi / 2) <= 0.25
    assert np.abs(cmds[:, 0]).max() <= 0.26 + 1e-9
    assert np.abs(cmds[:, 1]).max() <= 1.0 + 1e-9
    assert cmds[:, 0].max() > 0.25  # it does cruise at the desired speed on a straight line
    # acceleration limits hold between consecutive commands
    assert np.abs(np.diff(cmds[:, 0])).max() <= 2.5 * DT + 1e-9


def test_curved_path_is_followed(kit):
    t = np.linspace(0.0, math.pi, 80)
    path = np.stack([4.0 + 2.0 * np.sin(t), 2.0 - 2.0 * np.cos(t) + 0.0, t], axis=1)
    path[:, 1] += 2.0  # quarter..half circle from (4, 2) around to (4, 6)
    h, reached, cmds = _drive(kit, path, (4.0, 2.0, 0.0))
    assert reached
    assert math.hypot(h.pose[0] - path[-1, 0], h.pose[1] - path[-1, 1]) <= 0.25
    assert np.abs(cmds[:, 1]).max() <= 1.0 + 1e-9


def test_rotates_in_place_toward_a_path_behind_it(kit):
    path = _straight(3.0, 3.0, 0.8, 3.0, math.pi)
    ctl = make_controller(PARAMS)
    ctl.set_plan(path)
    res = ctl.compute_velocity((3.0, 3.0, 0.0), None, DT)
    assert res.status == "rotating" and res.v == 0.0 and res.w != 0.0
    h, reached, _ = _drive(kit, path, (3.0, 3.0, 0.0))
    assert reached


def test_final_rotation_to_goal_yaw():
    ctl = make_controller(PARAMS)
    path = _straight(0.0, 0.0, 1.0, 0.0, -math.pi / 2)
    ctl.set_plan(path)
    res = ctl.compute_velocity((0.95, 0.0, 0.0), None, DT)
    assert res.status == "rotating" and res.v == 0.0 and res.w < 0.0


def test_collision_check_finds_the_first_bad_pose_of_the_projected_arc():
    """The controller's point-by-point check against the whole arc (arc_poses) looked up at once (costs_at)."""
    rng = np.random.default_rng(4)
    data = np.where(rng.random((80, 80)) < 0.03, LETHAL_COST, 0).astype(np.uint8)
    data[rng.random((80, 80)) < 0.03] = 253  # inscribed cells
    cm = Costmap2D(data, 0.05, -2.0, -2.0)
    ctl = make_controller(PARAMS)
    hits = 0
    for _ in range(400):
        pose = (float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-1.5, 1.5)), float(rng.uniform(-math.pi, math.pi)))
        v, w = float(rng.uniform(0.01, 0.26)), float(rng.choice([0.0, rng.uniform(-1.0, 1.0)]))
        carrot = float(rng.uniform(0.0, 1.0))
        got = ctl._collision_ahead(pose, v, w, carrot, cm)
        horizon = float(ctl.p["max_allowed_time_to_collision_up_to_carrot"])
        dist = min(max(v * horizon, 0.1), max(carrot, 0.1))
        poses = arc_poses(pose, v, w, dist / v, min(max(0.025 / v, 1e-3), dist / v))
        costs = costs_at(cm, poses[:, 0], poses[:, 1])
        here = int(costs_at(cm, np.array([pose[0]]), np.array([pose[1]]))[0])
        threshold = LETHAL_COST if 253 <= here < 255 else 253
        bad = np.flatnonzero((costs >= threshold) & (costs != 255))
        if len(bad) == 0:
            assert got is None
        else:
            hits += 1
            assert got is not None
            hit = poses[bad[0]]
            assert got[:2] == pytest.approx((hit[0], hit[1]), abs=1e-9)
            assert abs(math.remainder(got[2] - hit[2], 2 * math.pi)) < 1e-9
    assert 50 < hits < 350  # both outcomes were checked


def test_collision_ahead_on_local_costmap_stops():
    data = np.zeros((60, 60), dtype=np.uint8)
    data[:, 30:32] = LETHAL_COST  # wall at x = 1.8 .. 1.92
    cm = Costmap2D(data, 0.06, 0.0, 0.0)
    ctl = make_controller(PARAMS)
    ctl.set_plan(_straight(1.0, 1.8, 3.0, 1.8, 0.0))
    ctl.last_cmd = (0.26, 0.0)
    res = ctl.compute_velocity((1.55, 1.8, 0.0), cm, DT)
    assert res.status == "collision" and res.v == 0.0 and res.w == 0.0
    # far from the wall the same plan is followed
    ok = ctl.compute_velocity((0.3, 1.8, 0.0), cm, DT)
    assert ok.status == "ok" and ok.v > 0.0


def test_cost_regulation_slows_near_obstacles():
    free = Costmap2D(np.zeros((60, 60), dtype=np.uint8), 0.06, 0.0, 0.0)
    near = Costmap2D(np.full((60, 60), 200, dtype=np.uint8), 0.06, 0.0, 0.0)
    speeds = []
    for cm in (free, near):
        ctl = make_controller(PARAMS)
        ctl.set_plan(_straight(0.5, 1.0, 3.0, 1.0, 0.0))
        ctl.last_cmd = (0.26, 0.0)
        speeds.append(ctl.compute_velocity((0.5, 1.0, 0.0), cm, DT).v)
    assert speeds[1] < speeds[0]
    assert speeds[1] >= 0.1 - 1e-9  # never below regulated_linear_scaling_min_speed


def test_curvature_regulation_slows_in_tight_turns():
    ctl = RegulatedPurePursuit(PARAMS.rpp)
    t = np.linspace(0.0, math.pi / 2, 40)
    ctl.set_plan(np.stack([0.4 * np.sin(t), 0.4 - 0.4 * np.cos(t), t], axis=1))
    ctl.last_cmd = (0.26, 0.0)
    res = ctl.compute_velocity((0.0, 0.0, 0.0), None, DT)
    assert 0.0 < res.v < 0.26


def test_empty_or_bad_plan_rejected():
    ctl = RegulatedPurePursuit(PARAMS.rpp)
    with pytest.raises(ValueError):
        ctl.set_plan(np.zeros((0, 3)))
    with pytest.raises(ValueError):
        ctl.set_plan(np.array([[0.0, float("nan"), 0.0]]))
    assert ctl.compute_velocity((0.0, 0.0, 0.0), None, DT).status == "invalid_path"


def test_goal_checker_xy_then_yaw_and_stateful():
    g = GoalChecker(0.25, 0.25, stateful=True)
    goal = (1.0, 1.0, 0.0)
    assert not g.is_goal_reached((0.0, 0.0, 0.0), goal)
    assert not g.is_goal_reached((1.1, 1.0, 1.0), goal)  # xy ok, yaw not
    assert g.is_goal_reached((1.3, 1.0, 0.1), goal)  # xy latched, yaw ok
    g2 = GoalChecker(0.25, 0.25, stateful=False)
    g2.is_goal_reached((1.1, 1.0, 1.0), goal)
    assert not g2.is_goal_reached((1.3, 1.0, 0.1), goal)


def test_progress_checker():
    p = ProgressChecker(0.5, 10.0)
    assert p.check((0.0, 0.0, 0.0), 0.0)
    assert p.check((0.3, 0.0, 0.0), 9.0)
    assert not p.check((0.3, 0.0, 0.0), 10.5)
    p.reset()
    assert p.check((0.3, 0.0, 0.0), 11.0)
    assert p.check((0.9, 0.0, 0.0), 20.0)  # moved > 0.5 m: new baseline
    assert p.check((0.9, 0.0, 0.0), 29.0)


def test_geometry_helpers():
    cm = Costmap2D(np.zeros((10, 10), dtype=np.uint8), 0.1, 0.0, 0.0)
    cm.data[5, 5] = LETHAL_COST
    assert list(costs_at(cm, np.array([0.55, -1.0]), np.array([0.55, 0.0]))) == [LETHAL_COST, 255]
    assert footprint_in_collision(cm, 0.55, 0.35, 0.175)[0]
    assert not footprint_in_collision(cm, 0.2, 0.2, 0.175)[0]
    arc = arc_poses((0.0, 0.0, 0.0), 0.5, 0.5, 1.0, 0.1)
    assert arc.shape == (10, 3)
    radius = 0.5 / 0.5
    assert abs(math.hypot(arc[-1, 0], arc[-1, 1]) - 2 * radius * math.sin(0.25)) < 1e-9  # chord of the arc
