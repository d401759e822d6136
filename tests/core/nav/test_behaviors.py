"""Behaviour-server tasks (spin, backup, drive_on_heading, wait, assisted_teleop): motion, results and codes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.nav.behaviors import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait
from tb4.nav.controller import LETHAL_COST, footprint_in_collision
from tb4.nav.costmap import Costmap2D
from tb4.nav.params import load_nav2_params
from tb4.nav.tasks import NavContext

pytestmark = pytest.mark.core


def test_spin_turns_by_target_and_reports(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.run(h.core.start_spin(math.pi / 2, time_allowance=10.0), 15.0)
    assert task.status == "succeeded", task.result()
    h.settle(0.5)
    assert kit.yaw_error(h.pose[2], math.pi / 2) < 0.1
    assert task.feedback()["angular_distance_traveled"] == pytest.approx(math.pi / 2, abs=0.05)
    res = task.result()
    assert res["error_code"] == 0 and 1.0 < res["total_elapsed_time"] < 10.0
    assert h.max_command()[1] <= 1.0 + 1e-9
    # negative target turns clockwise
    task = h.run(h.core.start_spin(-math.pi / 2), 15.0)
    assert task.status == "succeeded"
    h.settle(0.5)
    assert kit.yaw_error(h.pose[2], 0.0) < 0.1


def test_spin_timeout(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.run(h.core.start_spin(2 * math.pi, time_allowance=1.0), 5.0)
    assert task.status == "failed"
    assert task.result()["error_code"] == Spin.TIMEOUT == 701
    assert "time allowance" in task.result()["error_msg"]


def _ctx_with_costmap(pose, costmap):
    sent = []
    ctx = NavContext(
        params=load_nav2_params(),
        pose_fn=lambda: pose,
        local_pose_fn=lambda: pose,
        velocity_fn=lambda: (0.0, 0.0),
        send_fn=lambda v, w: sent.append((v, w)),
        local_costmap_fn=lambda: costmap,
    )
    return ctx, sent


def test_spin_collision_when_obstacle_inside_footprint():
    data = np.zeros((40, 40), dtype=np.uint8)
    data[21, 22] = LETHAL_COST  # 0.1 m from the robot centre at (1.2, 1.2)
    ctx, sent = _ctx_with_costmap((1.2, 1.2, 0.0), Costmap2D(data, 0.06, 0.0, 0.0))
    task = Spin(1.0)
    task.step(ctx, 0.0)
    task.step(ctx, 0.05)
    assert task.status == "failed" and task.result()["error_code"] == 703
    assert sent[-1] == (0.0, 0.0)
    ok = Spin(1.0, disable_collision_checks=True)
    ok.step(ctx, 0.0)
    ok.step(ctx, 0.05)
    assert ok.status == "running" and sent[-1][1] > 0.0


def test_backup_reverses_distance(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.run(h.core.start_backup(0.3, 0.15), 10.0)
    assert task.status == "succeeded", task.result()
    h.settle(0.5)
    assert h.pose[0] == pytest.approx(1.7, abs=0.05) and h.pose[1] == pytest.approx(2.0, abs=0.02)
    assert task.feedback()["distance_traveled"] == pytest.approx(0.3, abs=0.03)
    assert all(v <= 0.0 for _, v, _ in h.commands)


def test_backup_into_wall_is_collision_ahead(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (0.6, 2.0, 0.0))  # wall 0.55 m behind the centre
    task = h.run(h.core.start_backup(1.0, 0.2), 10.0)
    assert task.status == "failed"
    assert task.result()["error_code"] == BackUp.COLLISION_AHEAD == 714
    assert h.pose[0] > 0.175 + 0.05  # stopped before touching the wall
    assert h.sim.pop_hazards() == []


def test_backup_and_drive_on_heading_invalid_input(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.run(h.core.start_backup(0.3, 0.1, target_y=0.5), 1.0)
    assert task.result()["error_code"] == BackUp.INVALID_INPUT == 713
    task = h.run(h.core.start_drive_on_heading(0.3, -0.1), 1.0)
    assert task.result()["error_code"] == DriveOnHeading.INVALID_INPUT == 724
    assert "signs" in task.result()["error_msg"]


def test_drive_on_heading_forward_and_timeout(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (1.0, 1.0, math.pi / 4))
    task = h.run(h.core.start_drive_on_heading(0.5, 0.2), 10.0)
    assert task.status == "succeeded"
    h.settle(0.5)
    assert math.hypot(h.pose[0] - 1.0, h.pose[1] - 1.0) == pytest.approx(0.5, abs=0.05)
    slow = h.run(h.core.start_drive_on_heading(1.0, 0.05, time_allowance=2.0), 5.0)
    assert slow.result()["error_code"] == DriveOnHeading.TIMEOUT == 721


def test_wait_time_left_then_success(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.core.start_wait(1.0)
    h.run(task, 0.5)
    assert task.status == "running" and 0.4 < task.feedback()["time_left"] < 0.7
    h.run(task, 2.0)
    assert task.status == "succeeded" and task.result()["total_elapsed_time"] == pytest.approx(1.0, abs=0.06)
    assert (
        Wait(float("nan")).step(
            NavContext(load_nav2_params(), lambda: None, lambda: (0, 0, 0), lambda: (0, 0), lambda v, w: None), 0.0
        )
        == "failed"
    )


def test_assisted_teleop_passes_through_and_stops_before_wall(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.5, 2.0, 0.0))  # wall at x = 3.95
    task = h.core.start_assisted_teleop(time_allowance=0.0)
    for _ in range(200):  # 10 s of full-speed teleop toward the wall
        h.core.teleop_velocity(0.3, 0.0)
        h.tick()
    assert task.status == "running"
    assert task.feedback()["current_teleop_duration"] > 9.0
    assert h.max_command()[0] <= 0.26 + 1e-9  # clamped to the velocity smoother limit
    assert h.pose[0] < 3.95 - 0.175  # never touched the wall
    assert h.pose[0] > 3.0  # but it did drive
    assert h.sim.pop_hazards() == []
    assert h.core.preempt_teleop()
    h.tick()
    assert task.status == "succeeded" and task.result()["error_code"] == 0


def test_assisted_teleop_timeout(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0))
    task = h.run(h.core.start_assisted_teleop(time_allowance=1.0), 3.0)
    assert task.status == "failed" and task.result()["error_code"] == AssistedTeleop.TIMEOUT == 731


def test_behaviors_work_without_localization(kit):
    h = kit.Harness(kit.box_map(4.0, 4.0), (2.0, 2.0, 0.0), localize=False)
    task = h.run(h.core.start_spin(1.0), 10.0)
    assert task.status == "succeeded"


def test_backup_away_from_an_obstacle_touching_the_front(kit):
    # facing the west wall with the footprint already touching its costmap cells, as a docked robot is
    h = kit.Harness(kit.box_map(4.0, 4.0), (0.23, 2.0, math.pi))
    h.settle(0.1)
    assert footprint_in_collision(h.core.current_local_costmap(), 0.23, 2.0, 0.175)[0]
    task = h.run(h.core.start_backup(0.3, 0.15), 10.0)
    assert task.status == "succeeded", task.result()
    assert h.pose[0] > 0.45
    # but driving on into the wall is refused
    task = h.run(h.core.start_drive_on_heading(0.45, 0.1), 10.0)
    assert task.result()["error_code"] == DriveOnHeading.COLLISION_AHEAD
    assert h.pose[0] > 0.175 + 0.05 and h.sim.pop_hazards() == []
