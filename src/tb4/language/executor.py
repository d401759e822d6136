"""The safe executor for robot programs written by a language model (or by the offline interpreter).

Upstream hands the model's text to ``exec()``: whoever can publish on ``user_input`` (or a confused model) runs
arbitrary Python on the robot. Here a program is never given to ``exec``/``eval``. It goes through three stages,
one module each, under the bounds of `limits`:

1. `validate`: parse with ``ast``, accept only our straight-line subset, and only what Python's compiler accepts.
2. `plan`: our own interpreter evaluates it on plain data, within budgets (work, wall time, value sizes with
   sharing counted, memory), into a checked Plan. Every value is formatted through `bounded_format`.
3. `execute`: the plan runs on the navigator, one call at a time on one thread; a failed step stops it.

So a refused program is never partly executed: nothing touches the robot before the whole plan is known and valid.
This module gathers the public names and runs the three stages in one call.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping, Sequence
from typing import Any

from tb4.core.directions import DIRECTIONS
from tb4.language.limits import DEFAULT_LIMITS, Limits
from tb4.language.plan import PoseCheck, plan_program
from tb4.language.run_plan import ExecutionReport, execute_plan
from tb4.language.validate import validate
from tb4.language.vocabulary import (
    ALLOWED_METHODS,
    Plan,
    PlanningError,
    Pose,
    ProgramRejected,
    Step,
)

__all__ = [
    "DIRECTIONS",
    "ALLOWED_METHODS",
    "ProgramRejected",
    "PlanningError",
    "Limits",
    "DEFAULT_LIMITS",
    "Pose",
    "PoseCheck",
    "Step",
    "Plan",
    "ExecutionReport",
    "validate",
    "plan_program",
    "execute_plan",
    "run_program",
]


def run_program(
    source: str,
    navigator: Any,
    destinations: Mapping[str, Sequence[float]] | None = None,
    check_pose: PoseCheck | None = None,
    limits: Limits = DEFAULT_LIMITS,
    stop: threading.Event | None = None,
) -> tuple[Plan, ExecutionReport]:
    """Plan (raising ProgramRejected or PlanningError with nothing executed), then execute a program."""
    plan = plan_program(source, destinations, check_pose, limits)
    return plan, execute_plan(plan, navigator, limits, stop=stop)
