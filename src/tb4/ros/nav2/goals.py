"""Checking the goals of Nav2's actions before they reach the core: finite numbers, usable poses, and for the
planner a typed failure (which pose was bad) that maps to the action's own error code."""

from __future__ import annotations

import math
from typing import Any

from tb4.nav.planner import PlanError
from tb4.ros.convert import checked_pose, duration_to_seconds
from tb4.wire import get_optional

__all__ = ["PlanRequestError", "finite", "straight_line", "poses", "plan_start", "plan_goal", "plan_goals"]


class PlanRequestError(ValueError):
    """A compute_path request the planner cannot start on; `error` says why (START_/GOAL_OUTSIDE_MAP, TF_ERROR)."""

    def __init__(self, error: PlanError, message: str) -> None:
        super().__init__(message)
        self.error = error


def finite(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{what} must be finite, got {value}")
    return float(value)


def straight_line(goal: Any) -> tuple[float, float, float, bool, float, float]:
    """BackUp / DriveOnHeading goal -> (distance, speed, time_allowance, disable_collision_checks, y, z)."""
    return (
        finite(goal.target.x, "target.x"),
        finite(goal.speed, "speed"),
        duration_to_seconds(goal.time_allowance),
        bool(get_optional(goal, "disable_collision_checks", False)),
        finite(goal.target.y, "target.y"),
        finite(goal.target.z, "target.z"),
    )


def poses(messages: Any, allow_empty: bool = False) -> list[tuple[float, float, float]]:
    """(x, y, yaw) of each PoseStamped; ValueError naming the first bad one, or when none is given."""
    result = [checked_pose(p, f"pose {i}") for i, p in enumerate(messages)]
    if not result and not allow_empty:
        raise ValueError("no poses given")
    return result


def plan_start(goal: Any) -> tuple[float, float, float] | None:
    """A ComputePath goal's start pose (None: plan from the robot); a bad one is START_OUTSIDE_MAP."""
    if not goal.use_start:
        return None
    try:
        return checked_pose(goal.start, "start pose")
    except ValueError as exc:
        raise PlanRequestError(PlanError.START_OUTSIDE_MAP, str(exc)) from None


def plan_goal(msg: Any) -> tuple[float, float, float]:
    """ComputePathToPose's goal pose; a bad one is GOAL_OUTSIDE_MAP."""
    try:
        return checked_pose(msg, "goal pose")
    except ValueError as exc:
        raise PlanRequestError(PlanError.GOAL_OUTSIDE_MAP, str(exc)) from None


def plan_goals(messages: Any) -> list[tuple[float, float, float]]:
    """ComputePathThroughPoses' goals (empty is the planner's NO_VIAPOINTS_GIVEN); a bad one is GOAL_OUTSIDE_MAP."""
    try:
        return poses(messages, allow_empty=True)
    except ValueError as exc:
        raise PlanRequestError(PlanError.GOAL_OUTSIDE_MAP, str(exc)) from None
