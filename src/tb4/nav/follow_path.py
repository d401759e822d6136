"""FollowPath as a step-able task (the controller server's job: track a given path, no planning, no recoveries),
and the controller, goal checker and progress checker built from Nav2 parameters, which the navigators share."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from tb4.nav.controller import GoalChecker, ProgressChecker, RegulatedPurePursuit
from tb4.nav.params import Nav2Params
from tb4.nav.tasks import NOT_LOCALIZED_MSG, NavContext, Task

__all__ = ["make_controller", "make_goal_checker", "make_progress_checker", "FollowPath"]


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
