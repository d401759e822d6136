"""Navigator calls of a program, bound and checked into plan Steps (part of stage 2, plan).

Arguments are bound like Python binds them (positional, then keyword; a parameter given twice is refused),
numeric parameters are range-checked, poses must be finite and pass the world's goal check, and the number of
goals and robot actions is capped. Values quoted in a refusal go through the bounded formatter.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from tb4.language.bounded_format import bounded_repr, format_value
from tb4.language.limits import Limits
from tb4.language.plan_budget import Budget
from tb4.language.vocabulary import (
    ALLOWED_METHODS,
    GOAL_METHODS,
    LOG_METHODS,
    REQUIRED,
    MethodSpec,
    Plan,
    Pose,
    ProgramRejected,
    Step,
)

__all__ = ["PoseCheck", "StepBuilder", "is_number"]

#: check_pose(x, y): a problem text, or None when a goal there is fine.
PoseCheck = Callable[[float, float], "str | None"]


class StepBuilder:
    """Collects the Steps of one plan; `plan()` hands them over."""

    def __init__(self, limits: Limits, check_pose: PoseCheck | None, budget: Budget) -> None:
        self.limits = limits
        self.check_pose = check_pose
        self.budget = budget
        self._steps: list[Step] = []
        self.goals = 0

    def plan(self) -> Plan:
        return Plan(tuple(self._steps), self.goals)

    def call(self, method: str, args: list[Any], kwargs: list[tuple[str, Any]], line: int) -> Any:
        """Bind and check one navigator call: getPoseStamped returns a Pose, every other call adds a Step."""
        spec = ALLOWED_METHODS[method]
        bound = _bind(method, spec, args, kwargs, line)
        if method == "getPoseStamped":
            return self._pose(bound["position"], bound["rotation"], line)
        for name, (lo, hi) in spec.bounds.items():
            value = bound[name]
            if not is_number(value) or not math.isfinite(value) or not lo <= value <= hi:
                raise ProgramRejected(
                    f"navigator.{method}: {name}={bounded_repr(value, 60)} must be a number in [{lo:g}, {hi:g}]",
                    line,
                )
        if method == "startToPose":
            pose = bound["pose"]
            if not isinstance(pose, Pose):
                raise ProgramRejected("navigator.startToPose needs a pose from navigator.getPoseStamped", line)
            self._add_goals(1, line)
            self._check(pose, line)
            self._add(Step(method, (pose,), line))
        elif method in GOAL_METHODS:
            poses = bound["poses"]
            if not isinstance(poses, (list, tuple)) or not poses or not all(isinstance(p, Pose) for p in poses):
                raise ProgramRejected(f"navigator.{method} needs a non-empty list of poses from getPoseStamped", line)
            self._add_goals(len(poses), line)
            for pose in poses:
                self._check(pose, line)
            self._add(Step(method, (list(poses),), line))
        elif method in LOG_METHODS:
            text, _complete = format_value(bound["msg"], self.limits.max_string, text=True)
            message = "".join(c if c.isprintable() else " " for c in text)
            self._add(Step(method, (message,), line))
        else:
            self._add(Step(method, tuple(bound[name] for name, _ in spec.params), line))
        return None

    def _add(self, step: Step) -> None:
        if len(self._steps) >= self.limits.max_steps:
            raise ProgramRejected(f"too many robot actions (limit {self.limits.max_steps})", step.line)
        self._steps.append(step)

    def _add_goals(self, n: int, line: int) -> None:
        self.goals += n
        if self.goals > self.limits.max_goals:
            raise ProgramRejected(f"too many goals ({self.goals}, limit {self.limits.max_goals})", line)

    def _pose(self, position: Any, rotation: Any, line: int) -> Pose:
        if not isinstance(position, (list, tuple)) or len(position) != 2 or not all(is_number(v) for v in position):
            raise ProgramRejected(
                f"getPoseStamped: position must be [x, y] numbers, got {bounded_repr(position, 80)}", line
            )
        if not is_number(rotation):
            raise ProgramRejected(
                f"getPoseStamped: rotation must be a number of degrees, got {bounded_repr(rotation, 80)}", line
            )
        x, y, deg = float(position[0]), float(position[1]), float(rotation)
        if not all(math.isfinite(v) for v in (x, y, deg)):
            raise ProgramRejected(f"getPoseStamped: coordinates must be finite, got ({x}, {y}, {deg})", line)
        return Pose(x, y, deg)

    def _check(self, pose: Pose, line: int) -> None:
        if self.check_pose is None:
            return
        problem = self.check_pose(pose.x, pose.y)
        self.budget.check_deadline(line)
        if problem:
            raise ProgramRejected(f"goal ({pose.x:g}, {pose.y:g}) refused: {problem[:160]}", line)


def _bind(method: str, spec: MethodSpec, args: list[Any], kwargs: list[tuple[str, Any]], line: int) -> dict[str, Any]:
    names = [n for n, _ in spec.params]
    if len(args) > len(names):
        raise ProgramRejected(f"navigator.{method} takes at most {len(names)} arguments, got {len(args)}", line)
    bound = dict(zip(names, args, strict=False))
    for key, value in kwargs:
        if key not in names:
            raise ProgramRejected(f"navigator.{method} has no parameter {key[:40]!r}", line)
        if key in bound:
            raise ProgramRejected(f"navigator.{method}: {key} given twice", line)
        bound[key] = value
    for name, default in spec.params:
        if name not in bound:
            if default is REQUIRED:
                raise ProgramRejected(f"navigator.{method} is missing {name!r}", line)
            bound[name] = default
    return bound


def is_number(value: Any) -> bool:
    """An int or float, not a bool."""
    return isinstance(value, (int, float)) and not isinstance(value, bool)
