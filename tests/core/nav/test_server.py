"""NavigationCore: task management (preemption, cancel, pause), services, localization and nav2.yaml params."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.config import ConfigError
from tb4.nav.costmap import LETHAL
from tb4.nav.params import NAV2_YAML, load_nav2_params
from tb4.nav.server import PAUSED_MSG, NavigationCore, NotLocalizedError
from tb4.sim.obstacles import Obstacle

pytestmark = pytest.mark.core


def test_cancel_stops_the_robot(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    task = h.core.start_navigate_to_pose((5.0, 1.0, 0.0))
    h.run(task, 4.0)
    assert task.status == "running" and h.sim.velocity()[0] > 0.2
    h.core.cancel()
    assert task.status == "canceled" and not h.core.active
    assert h.commands[-1][1:] == (0.0, 0.0)
    h.settle(1.0)
    assert h.sim.velocity() == (0.0, 0.0)
    x = h.pose[0]
    h.settle(1.0)
    assert h.pose[0] == pytest.approx(x, abs=1e-9)


def test_new_task_preempts_running_one(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    first = h.core.start_navigate_to_pose((5.0, 1.0, 0.0))
    h.run(first, 3.0)
    second = h.core.start_navigate_to_pose((1.0, 4.0, math.pi / 2))
    assert first.status == "canceled" and h.core.task is second
    h.run(second, 60.0)
    assert second.status == "succeeded", second.result()
    assert math.hypot(h.pose[0] - 1.0, h.pose[1] - 4.0) <= 0.27
    spin = h.core.start_spin(1.0)
    h.core.start_wait(1.0)
    assert spin.status == "canceled"


def test_cancel_during_recovery_cancels_subtask(kit):
    grid = kit.box_map(6.0, 4.0, [(1.5, 1.6, 2.4, 4.0), (3.6, 1.6, 4.5, 4.0)])
    wall = Obstacle(shape="circle", radius=0.6, path=((3.0, 0.8),))
    h = kit.Harness(grid, (0.5, 0.8, 0.0), obstacles=[wall])
    task = h.core.start_navigate_to_pose((5.4, 0.8, 0.0))
    h.run(task, 60.0, until=lambda: task.recovery_task is not None)
    sub = task.recovery_task
    assert sub is not None and task.feedback()["number_of_recoveries"] >= 2
    h.core.cancel()
    assert task.status == "canceled" and sub.status == "canceled"


def test_paused_rejects_tasks_until_resumed(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    running = h.core.start_spin(3.0)
    h.run(running, 0.5)
    h.core.pause()
    assert running.status == "canceled"
    rejected = h.core.start_navigate_to_pose((2.0, 1.0, 0.0))
    assert rejected.status == "failed" and rejected.result()["error_msg"] == PAUSED_MSG
    assert rejected.result()["error_code"] == 9000
    h.core.resume()
    ok = h.run(h.core.start_navigate_to_pose((2.0, 1.0, 0.0)), 30.0)
    assert ok.status == "succeeded"


def test_compute_path_needs_localization_or_a_start(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), localize=False)
    with pytest.raises(NotLocalizedError, match="initialpose"):
        h.core.compute_path(None, (4.0, 4.0, 0.0))
    res = h.core.compute_path((1.0, 1.0, 0.0), (4.0, 4.0, 0.0))
    assert res.ok and np.allclose(res.path[-1, :2], (4.0, 4.0), atol=0.06)
    h.core.set_initial_pose(1.0, 1.0, 0.0)
    res = h.core.compute_path(None, (4.0, 4.0, 0.5))
    assert res.ok and np.allclose(res.path[0, :2], (1.0, 1.0), atol=0.06) and res.path[-1, 2] == pytest.approx(0.5)
    through = h.core.compute_path_through(None, [(4.0, 1.0, 0.0), (4.0, 4.0, 0.0)])
    assert through.ok and len(through.path) > len(res.path) / 2
    valid, bad = h.core.is_path_valid(res.path)
    assert valid and bad == []
    smoothed = h.core.smooth(res.path)
    assert smoothed.path.shape == res.path.shape


def test_planning_sees_live_obstacles_and_clearing_forgets_them(kit, open_map):
    box = Obstacle(shape="circle", radius=0.4, path=((2.5, 1.0),))
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), obstacles=[box])
    h.settle(0.2)  # a scan reaches the local costmap
    assert h.core.current_local_costmap().cost_at(2.1, 1.0) >= 253  # the obstacle's front face
    path = h.core.compute_path(None, (4.0, 1.0, 0.0)).path
    assert np.min(np.hypot(path[:, 0] - 2.5, path[:, 1] - 1.0)) > 0.4 + 0.175  # goes around the obstacle
    xs = np.linspace(1.5, 2.5, 40)
    valid, bad = h.core.is_path_valid(np.stack([xs, np.full(40, 1.0), np.zeros(40)], axis=1))
    assert not valid and bad and xs[bad[0]] > 1.8  # blocked where the lidar saw the obstacle's front
    h.core.clear_local()
    assert h.core.current_local_costmap().cost_at(2.1, 1.0) < 253
    # the global costmap's obstacle layer (on, as the TurtleBot 4 has it) keeps the mark until it is cleared too
    assert h.core.global_costmap.costmap.cost_at(2.1, 1.0) >= 253
    around = h.core.compute_path(None, (4.0, 1.0, 0.0)).path
    assert np.min(np.hypot(around[:, 0] - 2.5, around[:, 1] - 1.0)) > 0.4 + 0.175
    h.core.clear_global()
    straight = h.core.compute_path(None, (4.0, 1.0, 0.0)).path
    assert np.max(np.abs(straight[:, 1] - 1.0)) < 0.1
    h.settle(0.2)
    h.core.clear_local_around(0.5)  # only a 0.5 m square at the robot: the obstacle (1.5 m away) stays
    assert h.core.current_local_costmap().cost_at(2.1, 1.0) >= 253
    h.core.clear_local_except(0.5)
    assert h.core.current_local_costmap().cost_at(2.1, 1.0) < 253


def test_wrong_initial_pose_gives_wrong_map_pose(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), localize=False)
    assert h.core.pose() is None
    h.core.set_initial_pose(2.0, 1.0, 0.0)  # truth is (1, 1)
    task = h.run(h.core.start_navigate_to_pose((3.0, 1.0, 0.0)), 30.0)
    assert task.status == "succeeded"
    assert h.core.pose()[0] == pytest.approx(3.0, abs=0.27)
    assert h.pose[0] == pytest.approx(2.0, abs=0.27)  # the real robot is 1 m short, as on a real robot
    assert len(h.core.localizer.covariance()) == 36


def test_set_map_rebuilds_global_costmap(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    assert h.core.compute_path(None, (4.0, 1.0, 0.0)).ok
    walled = kit.box_map(6.0, 6.0, [(2.5, 0.0, 2.8, 6.0)])
    h.core.set_map(walled)
    res = h.core.compute_path(None, (4.0, 1.0, 0.0))
    assert not res.ok
    assert h.core.global_costmap.costmap.cost_at(2.6, 3.0) == LETHAL


def test_teleop_routing(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    assert not h.core.teleop_velocity(0.1, 0.0) and not h.core.preempt_teleop()
    task = h.core.start_assisted_teleop(5.0)
    h.core.teleop_velocity(0.2, 0.0)
    h.settle(0.3)
    assert task.last_command == (0.2, 0.0)
    h.settle(0.6)  # no new teleop command for > 0.5 s: stop
    assert task.last_command == (0.0, 0.0)


def test_nav2_params_defaults_and_validation(tmp_path):
    p = load_nav2_params()
    assert p.rpp["desired_linear_vel"] == 0.26 and p.max_angular_vel == 1.0
    assert p.goal_checker["xy_goal_tolerance"] == 0.25 and p.progress_checker["movement_time_allowance"] == 10.0
    assert p.global_costmap["inflation_layer"]["inflation_radius"] == 0.45 and p.planner["tolerance"] == 0.5
    assert p.waypoint_follower["wait_at_waypoint"]["waypoint_pause_duration"] == 200
    assert p.controller_period == pytest.approx(0.05)
    assert p.costmap_params("local").width == 3.0
    user = tmp_path / "nav2.yaml"
    user.write_text("controller_server:\n  ros__parameters:\n    FollowPath:\n      desired_linear_vell: 0.2\n")
    with pytest.raises(ConfigError) as err:
        load_nav2_params(user)
    msg = str(err.value)
    assert str(user) in msg and "desired_linear_vell" in msg and "did you mean 'desired_linear_vel'" in msg
    user.write_text("controller_server:\n  ros__parameters:\n    FollowPath:\n      desired_linear_vel: 0.2\n")
    p2 = load_nav2_params(user)
    assert p2.rpp["desired_linear_vel"] == 0.2 and p2.rpp["lookahead_dist"] == 0.6
    with pytest.raises(ConfigError, match="expected a number"):
        load_nav2_params(overrides={"amcl": {"ros__parameters": {"initial_cov_xx": "big"}}})
    with pytest.raises(ConfigError, match="must be > 0"):
        load_nav2_params(overrides={"controller_server": {"ros__parameters": {"controller_frequency": 0.0}}})
    assert NAV2_YAML.is_file()


def test_core_without_robot_can_plan(open_map):
    core = NavigationCore(open_map)
    res = core.compute_path((1.0, 1.0, 0.0), (3.0, 3.0, 0.0))
    assert res.ok
    core.step(0.0)  # no robot: nothing to do, must not fail


@pytest.mark.parametrize(("frequency", "updates"), [(1.0, 2), (5.0, 10)])
def test_the_global_costmap_takes_the_scan_at_its_update_frequency(kit, open_map, frequency, updates) -> None:
    """turtlebot4_navigation's global costmap updates at 1 Hz, the local one at 5 Hz: the global obstacle layer
    takes the latest scan once per its own period (the first at once), over the first 2 s of sim time."""
    params = load_nav2_params(overrides={"global_costmap": {"global_costmap": {"ros__parameters": {
        "update_frequency": frequency}}}})  # fmt: skip
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), params=params)
    scans: list[float] = []
    real = h.core.global_costmap.update_obstacles
    h.core.global_costmap.update_obstacles = lambda *a: (scans.append(h.core.now), real(*a))  # type: ignore[method-assign]
    task = h.core.start_navigate_to_pose((5.0, 1.0, 0.0))
    h.run(task, 2.0)
    assert len(scans) == updates, scans
    assert all(b - a == pytest.approx(1.0 / frequency) for a, b in zip(scans, scans[1:], strict=False))


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, math.inf, "fast"])
def test_a_global_costmap_update_frequency_that_is_not_a_positive_number_is_refused(bad) -> None:
    with pytest.raises(ConfigError, match="global_costmap.global_costmap.ros__parameters.update_frequency"):
        load_nav2_params(
            overrides={"global_costmap": {"global_costmap": {"ros__parameters": {"update_frequency": bad}}}}
        )
