"""NavigateToPose, NavigateThroughPoses, FollowWaypoints and FollowPath as step-able tasks.

This is the behaviour of Nav2's default tree (navigate_w_replanning_and_recovery) written as a small state
machine instead of a behaviour tree: plan from the localized pose, follow with RPP, replan every
`replan_period`, and when the path is blocked, no progress is made or planning fails, run recovery rounds in
Nav2's round-robin order (clear costmaps -> spin -> wait -> backup) up to `number_of_retries` times.

Error codes: a failure that no recovery can fix (goal outside the map, goal in an obstacle after clearing,
not localized) ends at once with the component's Nav2 code (e.g. ComputePathToPose 206 GOAL_OCCUPIED, as
Kilted's bt_navigator reports it) and the planner's message in error_msg; running out of recoveries ends with
the navigator's UNKNOWN code (9000 / 9100) and the last cause (with its code) in error_msg.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from tb4.core.geometry import Pose
from tb4.nav.behaviors import BackUp, Spin, Wait
from tb4.nav.controller import GoalChecker, ProgressChecker, RegulatedPurePursuit
from tb4.nav.params import Nav2Params
from tb4.nav.planner import PlanError, to_path_code, to_through_poses_code
from tb4.nav.tasks import FAILED, NOT_LOCALIZED_MSG, SUCCEEDED, NavContext, Task, WaypointStatusCode, waypoint_status

__all__ = [
    "make_controller",
    "make_goal_checker",
    "make_progress_checker",
    "NavigateThroughPoses",
    "NavigateToPose",
    "FollowWaypoints",
    "FollowPath",
    "RECOVERY_ORDER",
]

RECOVERY_ORDER = ("clear_costmaps", "spin", "wait", "backup")

# ComputePath* failures that no recovery can fix: fail at once (GOAL_OCCUPIED after one costmap clear).
_FATAL_PLAN_ERRORS = {"GOAL_OUTSIDE_MAP", "START_OUTSIDE_MAP", "NO_VIAPOINTS_GIVEN", "INVALID_PLANNER"}


def make_controller(params: Nav2Params) -> RegulatedPurePursuit:
    return RegulatedPurePursuit(
        params.rpp,
        max_linear_vel=params.max_linear_vel,
        max_angular_vel=params.max_angular_vel,
        xy_goal_tolerance=float(params.goal_checker["xy_goal_tolerance"]),
        robot_radius=float(params.local_costmap["robot_radius"]),
    )


def make_goal_checker(params: Nav2Params) -> GoalChecker:
    g = params.goal_checker
    return GoalChecker(float(g["xy_goal_tolerance"]), float(g["yaw_goal_tolerance"]), bool(g["stateful"]))


def make_progress_checker(params: Nav2Params) -> ProgressChecker:
    p = params.progress_checker
    return ProgressChecker(float(p["required_movement_radius"]), float(p["movement_time_allowance"]))


def _as_pose(goal: Sequence[float]) -> Pose:
    if len(goal) != 3:
        raise ValueError(f"a goal is (x, y, yaw), got {goal!r}")
    x, y, yaw = (float(v) for v in goal)
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"goal must be finite, got {(x, y, yaw)}")
    return (x, y, yaw)


class NavigateThroughPoses(Task):
    """Drive through `goals` in order (intermediate ones passed within `through_poses_radius`), stop at the last."""

    name = "navigate_through_poses"
    UNKNOWN, FAILED_TO_LOAD_BEHAVIOR_TREE, TF_ERROR, TIMEOUT = 9100, 9101, 9102, 9103
    _single = False

    def __init__(self, goals: Sequence[Sequence[float]]) -> None:
        super().__init__()
        self._raw_goals = list(goals)
        self.goals: list[Pose] = []
        self.statuses: list[dict[str, Any]] = []
        self.next_goal = 0
        self.number_of_recoveries = 0
        self.path: np.ndarray = np.zeros((0, 3))
        self.current_pose: Pose | None = None
        self.distance_remaining = 0.0
        self.estimated_time_remaining = 0.0
        self.last_cause: tuple[int, str] = (0, "")
        self._state = "init"
        self._recovery: Task | None = None
        self._last_plan = -math.inf
        self._blocked_since: float | None = None
        self._controller: RegulatedPurePursuit | None = None
        self._goal_checker: GoalChecker | None = None
        self._progress: ProgressChecker | None = None

    # --- helpers -------------------------------------------------------------------------------------
    def _plan_code(self, error: PlanError) -> int:
        return to_path_code(error) if self._single else to_through_poses_code(error)

    def _component(self) -> str:
        return "compute_path_to_pose" if self._single else "compute_path_through_poses"

    def _init(self, ctx: NavContext, now: float) -> bool:
        try:
            self.goals = [_as_pose(g) for g in self._raw_goals]
        except (TypeError, ValueError) as exc:
            self._fail(self.UNKNOWN, f"invalid goal: {exc}", now)
            return False
        self.statuses = [waypoint_status(i, g, WaypointStatusCode.PENDING) for i, g in enumerate(self.goals)]
        if not self.goals:
            self._fail(self._plan_code(PlanError.NO_VIAPOINTS_GIVEN), "no poses given to navigate through", now)
            return False
        self._controller = make_controller(ctx.params)
        self._goal_checker = make_goal_checker(ctx.params)
        self._progress = make_progress_checker(ctx.params)
        self._state = "plan"
        return True

    def _finish_fail(self, code: int, msg: str, now: float) -> None:
        if self.next_goal < len(self.statuses):
            self.statuses[self.next_goal].update(
                waypoint_status=WaypointStatusCode.FAILED, error_code=code, error_msg=msg
            )
        self._fail(code, msg, now)

    # --- main loop -----------------------------------------------------------------------------------
    def _step(self, ctx: NavContext, now: float) -> None:
        if self._state == "init" and not self._init(ctx, now):
            return
        pose = ctx.pose()
        if pose is None:
            self._finish_fail(self.TF_ERROR, NOT_LOCALIZED_MSG, now)
            return
        self.current_pose = pose
        if self._state == "recover":
            assert self._recovery is not None
            self._recovery.step(ctx, now)
            if not self._recovery.done:
                return
            self._recovery = None
            self._state = "plan"
            assert self._progress is not None
            self._progress.reset()
            self._blocked_since = None
        assert self._controller is not None and self._goal_checker is not None and self._progress is not None

        self._pass_goals(pose, ctx)
        # like Nav2's goal checker, judge arrival against the end of the plan (the planner may have moved a goal
        # that sits in an obstacle's inflation to the nearest reachable cell within its tolerance)
        final = self._controller.goal if self._state != "plan" and self._controller.goal else self.goals[-1]
        if self.next_goal >= len(self.goals) - 1 and self._goal_checker.is_goal_reached(pose, final):
            ctx.stop()
            for st in self.statuses:
                st["waypoint_status"] = WaypointStatusCode.COMPLETED
            self.next_goal = len(self.goals)
            self.distance_remaining = 0.0
            self.estimated_time_remaining = 0.0
            self._succeed(now)
            return

        replan_period = float(ctx.params.bt["replan_period"])
        if (self._state == "plan" or now - self._last_plan >= replan_period) and not self._plan(ctx, pose, now):
            return

        if not self._progress.check(pose, now):
            allowance = self._progress.allowance
            self._start_recovery(
                ctx, now, 105, f"follow_path: failed to make progress ({self._progress.radius} m in {allowance} s)"
            )
            return
        res = self._controller.compute_velocity(pose, ctx.local_costmap, ctx.params.controller_period)
        self.distance_remaining = self._controller.distance_remaining(pose)
        speed = abs(ctx.velocity()[0])
        self.estimated_time_remaining = self.distance_remaining / (
            speed if speed > 0.01 else self._controller.desired_v
        )
        if res.status == "collision":
            ctx.stop()
            if self._blocked_since is None:
                self._blocked_since = now
                self._last_plan = -math.inf  # replan at once: the merged costmap may route around the blockage
            elif now - self._blocked_since > float(ctx.params.bt["blocked_tolerance"]):
                self._start_recovery(ctx, now, 106, f"follow_path: no valid control, {res.message}")
            return
        self._blocked_since = None
        ctx.send_velocity(res.v, res.w)

    def _pass_goals(self, pose: Pose, ctx: NavContext) -> None:
        radius = float(ctx.params.bt["through_poses_radius"])
        while self.next_goal < len(self.goals) - 1:
            g = self.goals[self.next_goal]
            if math.hypot(g[0] - pose[0], g[1] - pose[1]) > radius:
                break
            self.statuses[self.next_goal]["waypoint_status"] = WaypointStatusCode.COMPLETED
            self.next_goal += 1
            self._last_plan = -math.inf

    def _plan(self, ctx: NavContext, pose: Pose, now: float) -> bool:
        assert self._controller is not None
        costmap = ctx.planning_costmap()
        remaining = self.goals[self.next_goal :]
        if ctx.planner is None or costmap is None:
            self._finish_fail(self._plan_code(PlanError.INVALID_PLANNER), "no planner or costmap available", now)
            return False
        if len(remaining) == 1:
            result = ctx.planner.plan(costmap, pose, remaining[0])
        else:
            result = ctx.planner.plan_through(costmap, pose, remaining)
        self._last_plan = now
        if result.ok:
            self.path = np.asarray(result.path, dtype=float)
            self._controller.set_plan(self.path)
            self._state = "follow"
            return True
        code = self._plan_code(result.error)
        msg = f"{self._component()} failed ({code} {result.error.name}): {result.message}"
        if result.error.name in _FATAL_PLAN_ERRORS or (
            result.error.name == "GOAL_OCCUPIED" and self.number_of_recoveries >= 1
        ):
            self._finish_fail(code, msg, now)
            return False
        self._start_recovery(ctx, now, code, msg)
        return False

    def _start_recovery(self, ctx: NavContext, now: float, code: int, msg: str) -> None:
        ctx.stop()
        self.last_cause = (code, msg)
        limit = int(ctx.params.bt["number_of_retries"])
        if self.number_of_recoveries >= limit:
            self._finish_fail(self.UNKNOWN, f"navigation failed after {limit} recoveries; last error: {msg}", now)
            return
        kind = RECOVERY_ORDER[self.number_of_recoveries % len(RECOVERY_ORDER)]
        self.number_of_recoveries += 1
        bt = ctx.params.bt
        assert self._controller is not None
        self._controller.last_cmd = (0.0, 0.0)
        if kind == "clear_costmaps":
            ctx.clear_costmaps()
            self._state = "plan"
            self._blocked_since = None
            assert self._progress is not None
            self._progress.reset()
            return
        if kind == "spin":
            self._recovery = Spin(float(bt["recovery_spin_dist"]), time_allowance=10.0)
        elif kind == "wait":
            self._recovery = Wait(float(bt["recovery_wait_duration"]))
        else:
            self._recovery = BackUp(float(bt["recovery_backup_dist"]), float(bt["recovery_backup_speed"]), 10.0)
        self._state = "recover"

    def _on_cancel(self) -> None:
        if self._recovery is not None:
            self._recovery.cancel()

    @property
    def recovery_task(self) -> Task | None:
        return self._recovery

    # --- action fields -------------------------------------------------------------------------------
    def _common_feedback(self) -> dict[str, Any]:
        return {
            "current_pose": self.current_pose if self.current_pose is not None else (0.0, 0.0, 0.0),
            "navigation_time": self.elapsed(),
            "estimated_time_remaining": float(self.estimated_time_remaining),
            "number_of_recoveries": int(self.number_of_recoveries),
            "distance_remaining": float(self.distance_remaining),
        }

    def feedback(self) -> dict[str, Any]:
        fb = self._common_feedback()
        fb["number_of_poses_remaining"] = max(0, len(self.goals) - self.next_goal)
        fb["waypoint_statuses"] = [dict(s) for s in self.statuses]
        return fb

    def result(self) -> dict[str, Any]:
        return {
            "error_code": self.error_code,
            "error_msg": self.error_msg,
            "waypoint_statuses": [dict(s) for s in self.statuses],
        }


class NavigateToPose(NavigateThroughPoses):
    """Drive to one (x, y, yaw) map-frame goal."""

    name = "navigate_to_pose"
    UNKNOWN, FAILED_TO_LOAD_BEHAVIOR_TREE, TF_ERROR, TIMEOUT = 9000, 9001, 9002, 9003
    _single = True

    def __init__(self, goal: Sequence[float]) -> None:
        super().__init__([goal])

    @property
    def goal(self) -> Sequence[float]:
        return self._raw_goals[0]

    def feedback(self) -> dict[str, Any]:
        return self._common_feedback()

    def result(self) -> dict[str, Any]:
        return {"error_code": self.error_code, "error_msg": self.error_msg}


class FollowWaypoints(Task):
    """Navigate to each waypoint in turn, pausing `waypoint_pause_duration` ms at each; missed ones are recorded."""

    name = "follow_waypoints"
    UNKNOWN, TASK_EXECUTOR_FAILED, NO_VALID_WAYPOINTS, STOP_ON_MISSED_WAYPOINT = 600, 601, 602, 603

    def __init__(
        self,
        goals: Sequence[Sequence[float]],
        number_of_loops: int = 0,
        goal_index: int = 0,
        stop_on_failure: bool | None = None,
        pause_duration: float | None = None,
    ) -> None:
        super().__init__()
        self._raw_goals = list(goals)
        self.goals: list[Pose] = []
        self.number_of_loops = int(number_of_loops)
        self.current_waypoint = int(goal_index)
        self.loop = 0
        self.stop_on_failure = stop_on_failure
        self.pause_duration = pause_duration
        self.missed_waypoints: list[dict[str, Any]] = []
        self.visited: list[int] = []
        self._nav: NavigateToPose | None = None
        self._pause_until: float | None = None
        self._started = False

    def _step(self, ctx: NavContext, now: float) -> None:
        if not self._started:
            self._started = True
            wf = ctx.params.waypoint_follower
            if self.stop_on_failure is None:
                self.stop_on_failure = bool(wf["stop_on_failure"])
            if self.pause_duration is None:
                pause = wf["wait_at_waypoint"]
                self.pause_duration = float(pause["waypoint_pause_duration"]) / 1000.0 if pause["enabled"] else 0.0
            try:
                self.goals = [_as_pose(g) for g in self._raw_goals]
            except (TypeError, ValueError) as exc:
                self._fail(self.NO_VALID_WAYPOINTS, f"invalid waypoint: {exc}", now)
                return
            if not self.goals:
                self._fail(self.NO_VALID_WAYPOINTS, "no waypoints given", now)
                return
            if not 0 <= self.current_waypoint < len(self.goals):
                self._fail(
                    self.NO_VALID_WAYPOINTS,
                    f"goal_index {self.current_waypoint} is outside the {len(self.goals)} waypoints given",
                    now,
                )
                return
            if self.number_of_loops < 0:
                self._fail(self.NO_VALID_WAYPOINTS, f"number_of_loops must be >= 0, got {self.number_of_loops}", now)
                return
            if ctx.pose() is None:
                self._fail(self.UNKNOWN, NOT_LOCALIZED_MSG, now)
                return
        if self._pause_until is not None:
            ctx.stop()
            if now + 1e-9 < self._pause_until:
                return
            self._pause_until = None
            self._advance(now)
            if self.done:
                return
        if self._nav is None:
            self._nav = NavigateToPose(self.goals[self.current_waypoint])
        self._nav.step(ctx, now)
        if not self._nav.done:
            return
        nav, self._nav = self._nav, None
        if nav.status == SUCCEEDED:
            self.visited.append(self.current_waypoint)
            self._pause_until = now + float(self.pause_duration or 0.0)
            return
        if nav.status == FAILED:
            self.missed_waypoints.append(
                waypoint_status(
                    self.current_waypoint,
                    self.goals[self.current_waypoint],
                    WaypointStatusCode.FAILED,
                    nav.error_code,
                    nav.error_msg,
                )
            )
            if self.stop_on_failure:
                self._fail(
                    self.STOP_ON_MISSED_WAYPOINT,
                    f"failed to reach waypoint {self.current_waypoint} and stop_on_failure is set: {nav.error_msg}",
                    now,
                )
                return
        self._advance(now)

    def _advance(self, now: float) -> None:
        self.current_waypoint += 1
        if self.current_waypoint >= len(self.goals):
            if self.loop >= self.number_of_loops:
                self.current_waypoint = len(self.goals) - 1
                self._succeed(now)
                return
            self.loop += 1
            self.current_waypoint = 0

    def _on_cancel(self) -> None:
        if self._nav is not None:
            self._nav.cancel()

    @property
    def navigation(self) -> NavigateToPose | None:
        return self._nav

    def feedback(self) -> dict[str, Any]:
        return {"current_waypoint": int(self.current_waypoint)}

    def result(self) -> dict[str, Any]:
        return {
            "missed_waypoints": [dict(m) for m in self.missed_waypoints],
            "error_code": self.error_code,
            "error_msg": self.error_msg,
        }


class FollowPath(Task):
    """Controller only: track a given path (N, 3) to its end; no planning, no recoveries (codes 1xx)."""

    name = "follow_path"
    UNKNOWN, INVALID_CONTROLLER, TF_ERROR, INVALID_PATH = 100, 101, 102, 103
    PATIENCE_EXCEEDED, FAILED_TO_MAKE_PROGRESS, NO_VALID_CONTROL, CONTROLLER_TIMED_OUT = 104, 105, 106, 107

    def __init__(self, path: np.ndarray | Sequence[Sequence[float]]) -> None:
        super().__init__()
        self._path_in = path
        self.distance_to_goal = 0.0
        self.speed = 0.0
        self._controller: RegulatedPurePursuit | None = None
        self._goal_checker: GoalChecker | None = None
        self._progress: ProgressChecker | None = None
        self._blocked_since: float | None = None
        self._new_path = True

    def set_path(self, path: np.ndarray | Sequence[Sequence[float]]) -> None:
        """Replace the path being followed (Nav2 lets a FollowPath goal be updated with a new path)."""
        self._path_in = path
        self._new_path = True

    def _step(self, ctx: NavContext, now: float) -> None:
        if self._controller is None:
            self._controller = make_controller(ctx.params)
            self._goal_checker = make_goal_checker(ctx.params)
            self._progress = make_progress_checker(ctx.params)
        assert self._goal_checker is not None and self._progress is not None
        pose = ctx.pose()
        if pose is None:
            self._fail(self.TF_ERROR, NOT_LOCALIZED_MSG, now)
            return
        if self._new_path:
            self._new_path = False
            try:
                path = np.asarray(self._path_in, dtype=float)
                if path.ndim != 2 or path.shape[1] not in (2, 3):
                    raise ValueError(f"expected an (N, 3) array of x, y, yaw, got shape {path.shape}")
                if path.shape[1] == 2:
                    yaw = np.arctan2(np.diff(path[:, 1]), np.diff(path[:, 0])) if len(path) > 1 else np.zeros(0)
                    path = np.column_stack([path, np.concatenate([yaw, [yaw[-1] if len(yaw) else pose[2]]])])
                self._controller.set_plan(path)
            except (TypeError, ValueError) as exc:
                self._fail(self.INVALID_PATH, f"invalid path: {exc}", now)
                return
            self._goal_checker.reset()
        goal = self._controller.goal
        assert goal is not None
        self.distance_to_goal = self._controller.distance_remaining(pose)
        self.speed = abs(ctx.velocity()[0])
        if self._goal_checker.is_goal_reached(pose, goal):
            ctx.stop()
            self.distance_to_goal = 0.0
            self._succeed(now)
            return
        if not self._progress.check(pose, now):
            self._fail(
                self.FAILED_TO_MAKE_PROGRESS,
                f"failed to make progress: moved less than {self._progress.radius} m in {self._progress.allowance} s",
                now,
            )
            return
        res = self._controller.compute_velocity(pose, ctx.local_costmap, ctx.params.controller_period)
        if res.status == "collision":
            ctx.stop()
            if self._blocked_since is None:
                self._blocked_since = now
            elif now - self._blocked_since > float(ctx.params.controller["failure_tolerance"]):
                self._fail(self.NO_VALID_CONTROL, f"no valid control: {res.message}", now)
            return
        self._blocked_since = None
        ctx.send_velocity(res.v, res.w)

    def feedback(self) -> dict[str, Any]:
        return {"distance_to_goal": float(self.distance_to_goal), "speed": float(self.speed)}

    def result(self) -> dict[str, Any]:
        return {"result": {}, "error_code": self.error_code, "error_msg": self.error_msg}
