"""What a program may say and what comes out of checking it: the allowed navigator methods,
the plan (Pose, Step, Plan), and the two ways checking can end without a plan (ProgramRejected, PlanningError).

Shared by the three stages (validate, plan, execute) and by the prompt and the offline interpreter, so the model
is told exactly the vocabulary the executor accepts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from tb4.language.bounded_format import bounded_repr, clip
from tb4.language.limits import DEFAULT_LIMITS

__all__ = [
    "ALLOWED_METHODS",
    "GOAL_METHODS",
    "BEHAVIOUR_METHODS",
    "LOG_METHODS",
    "REQUIRED",
    "MethodSpec",
    "ProgramRejected",
    "PlanningError",
    "Pose",
    "Step",
    "Plan",
]

REQUIRED: Any = object()  #: marks a parameter without a default


@dataclass(frozen=True)
class MethodSpec:
    """Parameters a navigator method accepts (name, default or REQUIRED), and numeric bounds per parameter."""

    params: tuple[tuple[str, Any], ...]
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)


#: The navigator methods a program may call. Nothing else is reachable from a program.
ALLOWED_METHODS: dict[str, MethodSpec] = {
    "dock": MethodSpec(()),
    "undock": MethodSpec(()),
    "getPoseStamped": MethodSpec((("position", REQUIRED), ("rotation", 0))),
    "startToPose": MethodSpec((("pose", REQUIRED),)),
    "startThroughPoses": MethodSpec((("poses", REQUIRED),)),
    "startFollowWaypoints": MethodSpec((("poses", REQUIRED),)),
    "info": MethodSpec((("msg", REQUIRED),)),
    "warn": MethodSpec((("msg", REQUIRED),)),
    "error": MethodSpec((("msg", REQUIRED),)),
    "debug": MethodSpec((("msg", REQUIRED),)),
    "cancelTask": MethodSpec(()),
    "spin": MethodSpec(
        (("spin_dist", 1.57), ("time_allowance", 10)),
        {"spin_dist": (-4 * math.pi, 4 * math.pi), "time_allowance": (1, 60)},
    ),
    "backup": MethodSpec(
        (("backup_dist", 0.15), ("backup_speed", 0.025), ("time_allowance", 10)),
        {"backup_dist": (0.0, 2.0), "backup_speed": (0.0, 0.31), "time_allowance": (1, 60)},
    ),
    "driveOnHeading": MethodSpec(
        (("dist", 0.15), ("speed", 0.025), ("time_allowance", 10)),
        {"dist": (0.0, 3.0), "speed": (0.0, 0.31), "time_allowance": (1, 60)},
    ),
}

#: Goal methods of the program and the non-blocking Nav2 call the executor makes for each.
GOAL_METHODS: dict[str, str] = {
    "startToPose": "goToPose",
    "startThroughPoses": "goThroughPoses",
    "startFollowWaypoints": "followWaypoints",
}
#: Behaviours: they start a task and return; the executor waits for it and checks its result.
BEHAVIOUR_METHODS = ("spin", "backup", "driveOnHeading")
LOG_METHODS = ("info", "warn", "error", "debug")


class ProgramRejected(Exception):
    """The program was refused (nothing was executed); `reason` says why, `line` where (0 when not known).

    The reason is cut to a few hundred characters: every part of it is formatted with a bound already, this is
    the last guard."""

    def __init__(self, reason: str, line: int = 0) -> None:
        self.reason = clip(str(reason), DEFAULT_LIMITS.max_message)
        self.line = int(line or 0)
        super().__init__(f"line {self.line}: {self.reason}" if self.line else self.reason)


class PlanningError(Exception):
    """Checking the program failed for a reason that is not the program's fault as such: the planner ran out of
    memory, recursed too deeply, or hit a bug. Nothing was executed; reported as what it is, not as a refusal."""

    def __init__(self, kind: str, detail: str = "") -> None:
        self.kind = kind
        self.detail = clip(str(detail), DEFAULT_LIMITS.max_message)
        super().__init__(f"{kind}: {self.detail}" if self.detail else kind)


@dataclass(frozen=True)
class Pose:
    """A pose a program asked for: map frame, metres, heading in degrees (TurtleBot4Directions convention)."""

    x: float
    y: float
    degrees: float

    def __bounded_format__(self) -> str:
        return f"({self.x:g}, {self.y:g}, {self.degrees:g}°)"


@dataclass(frozen=True)
class Step:
    """One navigator call of a plan, with its arguments already evaluated and checked."""

    method: str
    args: tuple[Any, ...] = ()
    line: int = 0

    def describe(self, limit: int = 200) -> str:
        inner = bounded_repr(list(self.args), limit)  # "[a, b]", or "[a, b…" when cut
        return f"{self.method}({inner[1:-1] if inner.endswith(']') else inner[1:]})"


@dataclass(frozen=True)
class Plan:
    """The checked list of navigator calls a program makes, and how many goal poses it sends."""

    steps: tuple[Step, ...]
    goals: int

    def describe(self, limit: int = 2000) -> str:
        return clip("; ".join(s.describe() for s in self.steps), limit) or "(no robot actions)"
