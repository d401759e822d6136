"""Navigators (navigate_to_pose / through_poses / follow_waypoints / follow_path) on the real Simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.nav.follow_path import FollowPath
from tb4.nav.navigate import NavigateThroughPoses, NavigateToPose
from tb4.nav.params import load_nav2_params
from tb4.nav.tasks import NOT_LOCALIZED_MSG, WaypointStatusCode
from tb4.nav.waypoints import FollowWaypoints
from tb4.sim.obstacles import Obstacle

pytestmark = pytest.mark.core

L_WALLS = [(0.0, 1.3, 3.6, 5.0)]  # leaves an L: bottom corridor y < 1.3, right corridor x > 3.6


def _assert_at(kit, h, goal, xy=0.25, yaw=0.25):
    x, y, th = h.pose
    assert math.hypot(x - goal[0], y - goal[1]) <= xy + 0.02, (h.pose, goal)
    assert kit.yaw_error(th, goal[2]) <= yaw + 0.05, (h.pose, goal)


def test_navigate_to_pose_open_map(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    goal = (4.5, 4.0, math.pi)
    task = h.core.start_navigate_to_pose(goal)
    h.run(task, 5.0)
    fb = task.feedback()
    assert set(fb) == {
        "current_pose",
        "navigation_time",
        "estimated_time_remaining",
        "number_of_recoveries",
        "distance_remaining",
    }
    assert 0.0 < fb["distance_remaining"] < 4.6 and fb["estimated_time_remaining"] > 0.0
    h.run(task, 60.0)
    assert task.status == "succeeded", task.result()
    assert task.result() == {"error_code": 0, "error_msg": ""}
    _assert_at(kit, h, goal)
    v, w = h.max_command()
    assert v <= 0.26 + 1e-9 and w <= 1.0 + 1e-9
    assert h.sim.pop_hazards() == []


def test_navigate_l_shaped_corridor(kit):
    h = kit.Harness(kit.box_map(5.0, 5.0, L_WALLS), (0.6, 0.65, 0.0))
    goal = (4.3, 4.3, math.pi / 2)
    task = h.run(h.core.start_navigate_to_pose(goal), 90.0)
    assert task.status == "succeeded", task.result()
    _assert_at(kit, h, goal)
    assert task.feedback()["number_of_recoveries"] == 0
    assert h.sim.pop_hazards() == []


def test_goal_inside_wall_fails_with_planner_reason(kit):
    h = kit.Harness(kit.box_map(5.0, 5.0, L_WALLS), (0.6, 0.65, 0.0))
    task = h.run(h.core.start_navigate_to_pose((1.8, 3.2, 0.0)), 30.0)
    assert task.status == "failed"
    res = task.result()
    assert res["error_code"] == 206  # ComputePathToPose GOAL_OCCUPIED, as Kilted's bt_navigator reports it
    assert "GOAL_OCCUPIED" in res["error_msg"] and "compute_path_to_pose" in res["error_msg"]
    outside = h.run(h.core.start_navigate_to_pose((20.0, 3.0, 0.0)), 5.0)
    assert outside.result()["error_code"] == 204 and "GOAL_OUTSIDE_MAP" in outside.result()["error_msg"]


def test_goal_before_localization_fails_clearly(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), localize=False)
    task = h.run(h.core.start_navigate_to_pose((3.0, 3.0, 0.0)), 2.0)
    assert task.status == "failed"
    assert task.result() == {"error_code": NavigateToPose.TF_ERROR, "error_msg": NOT_LOCALIZED_MSG}
    assert task.result()["error_code"] == 9002
    assert "initialpose" in task.result()["error_msg"]


def test_invalid_goal_rejected(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    task = h.run(h.core.start_navigate_to_pose((float("nan"), 1.0, 0.0)), 1.0)
    assert task.status == "failed" and task.result()["error_code"] == 9000 and "finite" in task.result()["error_msg"]


def _blocked_corridor(kit, speed: float):
    """A corridor (y < 1.6) that is the only way east, with an alcove above it at x 2.4..3.6 where a big
    obstacle moves out of (and later back into) the corridor."""
    grid = kit.box_map(6.0, 4.0, [(1.5, 1.6, 2.4, 4.0), (3.6, 1.6, 4.5, 4.0)])
    obstacle = Obstacle(shape="circle", radius=0.6, path=((3.0, 0.8), (3.0, 3.3)), speed=speed, mode="pingpong")
    return kit.Harness(grid, (0.5, 0.8, 0.0), obstacles=[obstacle])


def test_recoveries_when_moving_obstacle_blocks_corridor_then_success(kit):
    h = _blocked_corridor(kit, speed=0.02)
    goal = (5.4, 0.8, 0.0)
    task = h.run(h.core.start_navigate_to_pose(goal), 120.0)
    assert task.status == "succeeded", task.result()
    assert task.feedback()["number_of_recoveries"] >= 1
    _assert_at(kit, h, goal)
    assert h.sim.pop_hazards() == []  # it waited instead of pushing into the obstacle


def test_permanently_blocked_corridor_fails_with_reason(kit):
    h = _blocked_corridor(kit, speed=0.0)  # never moves
    task = h.core.start_navigate_to_pose((5.4, 0.8, 0.0))
    kinds: list[str] = []

    def watch() -> bool:
        rec = task.recovery_task
        if rec is not None and (not kinds or kinds[-1] != f"{rec.name}@{id(rec)}"):
            kinds.append(f"{rec.name}@{id(rec)}")
        return False

    h.run(task, 200.0, until=watch)
    # Nav2's round robin: clear costmaps (no motion), spin, wait, backup, clear, spin
    assert [k.split("@")[0] for k in kinds] == ["spin", "wait", "backup", "spin"]
    assert task.status == "failed"
    res = task.result()
    assert res["error_code"] == NavigateToPose.UNKNOWN == 9000
    assert "after 6 recoveries" in res["error_msg"]
    assert task.feedback()["number_of_recoveries"] == 6
    assert h.sim.pop_hazards() == []


def test_navigate_through_poses_in_order(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    goals = [(1.5, 4.5, 0.0), (4.5, 4.5, 0.0), (4.5, 1.5, -math.pi / 2)]
    task = h.core.start_navigate_through_poses(goals)
    first_near = {}
    remaining = []

    def watch() -> bool:
        x, y, _ = h.pose
        for i, g in enumerate(goals):
            if i not in first_near and math.hypot(x - g[0], y - g[1]) < 0.5:
                first_near[i] = h.sim.time
        remaining.append(task.feedback()["number_of_poses_remaining"])
        return False

    h.run(task, 120.0, until=watch)
    assert task.status == "succeeded", task.result()
    assert sorted(first_near, key=first_near.get) == [0, 1, 2]
    assert remaining[0] == 3 and remaining[-1] == 0 and all(np.diff(remaining) <= 0)
    res = task.result()
    assert res["error_code"] == 0
    assert [s["waypoint_status"] for s in res["waypoint_statuses"]] == [WaypointStatusCode.COMPLETED] * 3
    _assert_at(kit, h, goals[-1])


def test_navigate_through_no_poses(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    task = h.run(h.core.start_navigate_through_poses([]), 1.0)
    assert task.result()["error_code"] == 309 and NavigateThroughPoses.UNKNOWN == 9100


def test_follow_waypoints_visits_in_order_and_records_missed(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    goals = [(2.5, 1.0, 0.0), (20.0, 20.0, 0.0), (2.5, 3.0, math.pi / 2)]
    task = h.core.start_follow_waypoints(goals)
    seen = []

    def watch() -> bool:
        cw = task.feedback()["current_waypoint"]
        if not seen or seen[-1] != cw:
            seen.append(cw)
        return False

    h.run(task, 60.0, until=watch)
    assert task.status == "succeeded", task.result()
    assert seen[0] == 0 and seen[-1] == 2 and seen == sorted(seen)  # waypoint 1 fails within one step
    assert task.visited == [0, 2]
    res = task.result()
    assert res["error_code"] == 0
    assert len(res["missed_waypoints"]) == 1
    missed = res["missed_waypoints"][0]
    assert missed["waypoint_index"] == 1 and missed["waypoint_status"] == WaypointStatusCode.FAILED
    assert missed["error_code"] == 204 and missed["waypoint_pose"] == (20.0, 20.0, 0.0)
    _assert_at(kit, h, goals[-1])


def test_follow_waypoints_pauses_at_each_waypoint(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    task = h.core.start_follow_waypoints([(1.8, 1.0, 0.0)])
    h.run(task, 30.0, until=lambda: task.visited == [0])
    t_reached = h.sim.time
    h.run(task, 5.0)
    assert task.status == "succeeded"
    assert h.sim.time - t_reached == pytest.approx(0.2, abs=0.06)  # waypoint_pause_duration 200 ms


def test_follow_waypoints_loops_and_goal_index(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    goals = [(2.0, 1.0, 0.0), (2.0, 2.0, math.pi)]
    task = h.run(h.core.start_follow_waypoints(goals, number_of_loops=1, goal_index=1), 90.0)
    assert task.status == "succeeded", task.result()
    assert task.visited == [1, 0, 1]
    assert [m["current_waypoint"] for m in task.drain_phase_feedback()] == [1, 0, 1]  # each one begun, in order


def test_follow_waypoints_stop_on_failure_and_bad_input(kit, open_map):
    params = load_nav2_params(overrides={"waypoint_follower": {"ros__parameters": {"stop_on_failure": True}}})
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), params=params)
    task = h.run(h.core.start_follow_waypoints([(20.0, 1.0, 0.0), (2.0, 1.0, 0.0)]), 10.0)
    assert task.status == "failed"
    assert task.result()["error_code"] == FollowWaypoints.STOP_ON_MISSED_WAYPOINT == 603
    assert task.result()["missed_waypoints"][0]["waypoint_index"] == 0
    assert h.run(h.core.start_follow_waypoints([]), 1.0).result()["error_code"] == 602
    assert h.run(h.core.start_follow_waypoints([(2.0, 1.0, 0.0)], goal_index=3), 1.0).result()["error_code"] == 602


def test_follow_path_controller_only(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    xs = np.linspace(1.0, 4.0, 40)
    path = np.stack([xs, 1.0 + 0.3 * np.sin(xs), np.zeros_like(xs)], axis=1)
    task = h.core.start_follow_path(path)
    h.run(task, 3.0)
    fb = task.feedback()
    assert set(fb) == {"distance_to_goal", "speed"} and fb["speed"] > 0.1
    h.run(task, 40.0)
    assert task.status == "succeeded", task.result()
    assert task.result() == {"result": {}, "error_code": 0, "error_msg": ""}
    assert math.hypot(h.pose[0] - 4.0, h.pose[1] - (1.0 + 0.3 * math.sin(4.0))) <= 0.27
    bad = h.run(h.core.start_follow_path(np.zeros((0, 3))), 1.0)
    assert bad.result()["error_code"] == FollowPath.INVALID_PATH == 103


def test_follow_path_blocked_is_no_valid_control(kit):
    grid = kit.box_map(6.0, 3.0, [(3.0, 0.0, 3.3, 3.0)])  # wall across the whole room at x = 3
    h = kit.Harness(grid, (1.0, 1.5, 0.0))
    path = np.stack([np.linspace(1.0, 5.0, 50), np.full(50, 1.5), np.zeros(50)], axis=1)
    task = h.run(h.core.start_follow_path(path), 40.0)
    assert task.status == "failed"
    assert task.result()["error_code"] == FollowPath.NO_VALID_CONTROL == 106
    assert h.pose[0] < 3.0 - 0.175 and h.sim.pop_hazards() == []


def test_goal_in_wall_inflation_is_reached_at_the_plan_end(kit, open_map):
    h = kit.Harness(open_map, (2.0, 3.0, 0.0))
    goal = (0.12, 3.0, math.pi)  # 0.07 m from the wall: unreachable for the centre, within planner tolerance
    task = h.run(h.core.start_navigate_to_pose(goal), 40.0)
    assert task.status == "succeeded", task.result()
    assert h.pose[0] < 0.6 and h.sim.pop_hazards() == []


def test_external_cancel_sends_a_stop(kit, open_map):
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    task = h.core.start_navigate_to_pose((5.0, 1.0, 0.0))
    h.run(task, 3.0)
    task.cancel()  # what a ROS cancel callback does
    h.tick()
    assert h.commands[-1][1:] == (0.0, 0.0)


# --- the moments a client must see, whenever the bridge samples (PhaseLog) ---------------------------------------
def test_a_whole_drive_between_two_samples_still_reports_its_start_and_each_pose_passed(kit, open_map):
    """Nobody samples the feedback until the task ends (a starved server thread at --rate max): what was marked
    still says where the drive started, how far it had to go, and each pose passed, in order."""
    h = kit.Harness(open_map, (1.0, 1.0, 0.0))
    goals = [(1.5, 4.5, 0.0), (4.5, 4.5, 0.0), (4.5, 1.5, -math.pi / 2)]
    task = h.run(h.core.start_navigate_through_poses(goals), 120.0)
    assert task.status == "succeeded", task.result()
    marked = task.drain_phase_feedback()
    start = marked[0]
    assert start["number_of_poses_remaining"] == 3 and start["distance_remaining"] > 3.0
    assert (
        start["navigation_time"] < 0.5
        and math.hypot(start["current_pose"][0] - 1.0, start["current_pose"][1] - 1.0) < 0.1
    )
    assert [m["number_of_poses_remaining"] for m in marked] == [3, 2, 1]
    assert [m["number_of_recoveries"] for m in marked] == [0, 0, 0]
    assert task.drain_phase_feedback() == []  # each moment is reported once


def test_each_recovery_begun_is_marked(kit):
    h = _blocked_corridor(kit, speed=0.0)
    task = h.run(h.core.start_navigate_to_pose((5.4, 0.8, 0.0)), 200.0)
    assert task.status == "failed"
    recoveries = [m["number_of_recoveries"] for m in task.drain_phase_feedback()]
    assert recoveries == [0, 1, 2, 3, 4, 5, 6]  # the drive's start, then each of the six rounds
