"""Measure a command interpreter on the evaluation set (eval_commands.yaml) by comparing the robot actions.

A command counts as right when the program it produced plans (through the safe executor) to exactly the expected
actions, or, for commands that must be refused, when no program was produced. The baseline is exact-name matching
only: "dock"/"undock" as the whole command, or a destination's exact name somewhere in it.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from tb4.config import load_yaml
from tb4.language.offline import OfflineInterpreter
from tb4.language.plan import plan_program
from tb4.language.vocabulary import Plan, PlanningError, ProgramRejected
from tb4.language.world_context import DOCK_DESTINATION, destination_table, pose_checker
from tb4.sim.world import World

__all__ = [
    "EVAL_FILE",
    "HELDOUT_FILE",
    "EvalCase",
    "EvalResult",
    "load_eval_set",
    "canonical_actions",
    "exact_name_baseline",
    "evaluate",
    "offline_interpreter",
]

EVAL_FILE = Path(__file__).resolve().parent / "eval_commands.yaml"
# Written before the interpreter ever saw it, and never tuned on: accuracy on commands it has not seen.
HELDOUT_FILE = Path(__file__).resolve().parent / "eval_commands_heldout.yaml"

#: An interpreter: text -> program (None = not understood).
Interpreter = Callable[[str], "str | None"]


@dataclass(frozen=True)
class EvalCase:
    text: str
    expect: tuple[str, ...] | None  # None: must be refused


@dataclass(frozen=True)
class EvalResult:
    case: EvalCase
    got: tuple[str, ...] | None
    correct: bool
    note: str = ""


def load_eval_set(path: Path = EVAL_FILE) -> list[EvalCase]:
    raw = load_yaml(path)
    cases = []
    for i, item in enumerate(raw.get("commands", [])):
        text = str(item.get("text", ""))
        expect = item.get("expect")
        if expect == "refuse":
            cases.append(EvalCase(text, None))
        elif isinstance(expect, list) and expect:
            cases.append(EvalCase(text, tuple(_normalise_action(str(a)) for a in expect)))
        else:
            raise ValueError(f"{path}: commands[{i}].expect must be 'refuse' or a list of actions, got {expect!r}")
    return cases


def _num(value: float) -> str:
    rounded = round(float(value), 2)
    return f"{rounded:g}" if rounded != 0 else "0"


def _normalise_action(action: str) -> str:
    def fix(match: re.Match[str]) -> str:
        return _num(float(match.group(0)))

    return re.sub(r"-?\d+(?:\.\d+)?", fix, " ".join(action.split()))


def canonical_actions(plan: Plan) -> tuple[str, ...]:
    """A plan as comparable action strings (see eval_commands.yaml)."""
    out = []
    for step in plan.steps:
        m = step.method
        if m in ("dock", "undock"):
            out.append(m)
        elif m == "cancelTask":
            out.append("cancel")
        elif m == "startToPose":
            p = step.args[0]
            out.append(f"goto {_num(p.x)} {_num(p.y)} {_num(p.degrees % 360)}")
        elif m in ("startFollowWaypoints", "startThroughPoses"):
            kind = "waypoints" if m == "startFollowWaypoints" else "through"
            out.append(kind + " " + "; ".join(f"{_num(p.x)} {_num(p.y)} {_num(p.degrees % 360)}" for p in step.args[0]))
        elif m == "spin":
            out.append(f"spin {_num(step.args[0])}")
        elif m == "backup":
            out.append(f"backup {_num(step.args[0])}")
        else:
            out.append(m)
    return tuple(out)


DOCK_PROGRAM = (
    "navigator.startToPose(navigator.getPoseStamped(destinations['dock'][0:2], destinations['dock'][2]))\n"
    "navigator.dock()\n"
)


def exact_name_baseline(world: World) -> Interpreter:
    """Exact names only: 'dock' / 'undock' as the whole command, or a destination's exact name in the text."""
    names = sorted(world.destinations, key=len, reverse=True)

    def interpret(text: str) -> str | None:
        command = " ".join(re.sub(r"[^a-z0-9 ]", " ", text.lower()).split())
        if command == "undock":
            return "navigator.undock()"
        if command == "dock":
            return DOCK_PROGRAM
        for name in names:
            if re.search(rf"\b{re.escape(name)}\b", command):
                return (
                    f"navigator.startToPose(navigator.getPoseStamped(destinations[{name!r}][0:2], "
                    f"destinations[{name!r}][2]))"
                )
        return None

    return interpret


def offline_interpreter(world: World) -> Interpreter:
    interpreter = OfflineInterpreter(world.destinations.values(), DOCK_DESTINATION in destination_table(world))
    return lambda text: interpreter.interpret(text).program


def evaluate(interpret: Interpreter, world: World, cases: Sequence[EvalCase] | None = None) -> list[EvalResult]:
    """Run every case through `interpret` and the executor's planner; compare actions."""
    cases = load_eval_set() if cases is None else cases
    table = destination_table(world)
    check = pose_checker(world)
    results = []
    for case in cases:
        program = interpret(case.text)
        if program is None:
            results.append(EvalResult(case, None, case.expect is None))
            continue
        try:
            got = canonical_actions(plan_program(program, table, check))
        except (ProgramRejected, PlanningError) as exc:
            results.append(EvalResult(case, None, False, f"program refused by the executor: {exc}"))
            continue
        results.append(EvalResult(case, got, got == case.expect))
    return results
