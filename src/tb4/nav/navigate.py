"""NavigateToPose and NavigateThroughPoses as step-able tasks: bt_navigator's job (FollowWaypoints is in
waypoints.py, FollowPath and the controller set-up in follow_path.py).

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
from tb4.nav.follow_path import make_controller, make_goal_checker, make_progress_checker
from tb4.nav.planner import PlanError, to_path_code, to_through_poses_code
from tb4.nav.tasks import NOT_LOCALIZED_MSG, NavContext, Task, WaypointStatusCode, waypoint_status

__all__ = ["RECOVERY_ORDER", "as_goal_pose", "NavigateThroughPoses", "NavigateToPose"]

RECOVERY_ORDER = ("clear_costmaps", "spin", "wait", "backup")

# ComputePath* failures that no recovery can fix: fail at once (GOAL_OCCUPIED after one costmap clear).
_FATAL_PLAN_ERRORS = {"GOAL_OUTSIDE_MAP", "START_OUTSIDE_MAP", "NO_VIAPOINTS_GIVEN", "INVALID_PLANNER"}


def as_goal_pose(goal: Sequence[float]) -> Pose:
    """A goal given as (x, y, yaw), checked: three finite numbers."""
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
        self._drove = False

    # --- helpers -------------------------------------------------------------------------------------
    def _plan_code(self, error: PlanError) -> int:
        return to_path_code(error) if self._single else to_through_poses_code(error)

    def _component(self) -> str:
        return "compute_path_to_pose" if self._single else "compute_path_through_poses"

    def _init(self, ctx: NavContext, now: float) -> bool:
        try:
            self.goals = [as_goal_pose(g) for g in self._raw_goals]
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
        if not self._drove:  # the drive starts: where from, and how far to go
            self._drove = True
            self.phases.mark(self.feedback())
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
            self.phases.mark(self.feedback())

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
        self.phases.mark(self.feedback())
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

    def abort(self, code: int, msg: str, now: float) -> None:
        """End it failed from outside; the pose being driven to is marked failed with the cause.

        Args:
            code: the action's error code for the result.
            msg: why, for the result's error_msg and the pose's status.
            now: sim time of the end.
        """
        if not self.done and self.next_goal < len(self.statuses):
            self.statuses[self.next_goal].update(
                waypoint_status=WaypointStatusCode.FAILED, error_code=int(code), error_msg=msg
            )
        super().abort(code, msg, now)

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
