"""Random programs in (and just outside) the executor's language: every one either plans or is refused with a
short reason, quickly; none reaches a planner error (that would be a bug in the planner, not a refusal)."""

from __future__ import annotations

import random
import time

import pytest

from tb4.language.executor import Plan, PlanningError, ProgramRejected, plan_program

NAMES = ["a", "b", "c", "L", "S", "P"]
ATOMS = [
    "0",
    "1",
    "-2.5",
    "1e6",
    "1e300",
    "'x'",
    "'" + "y" * 200 + "'",
    "None",
    "True",
    "destinations['wood crate']",
    "destinations['dock'][0:2]",
    "TurtleBot4Directions.EAST",
    "navigator.getPoseStamped([1.0, 1.0], 90)",
    "navigator.getPoseStamped(destinations['wood crate'][0:2], destinations['wood crate'][2])",
]
INDEXES = ["0", "-1", "1:", "::2", "'k'"]
SINKS = [
    "navigator.info({})",
    "x = destinations[{}]",
    "navigator.spin({})",
    "navigator.backup(backup_dist={})",
    "navigator.startToPose({})",
    "navigator.startFollowWaypoints({})",
    "navigator.getPoseStamped({}, 0)",
    "x = {} == {}",
    "x = [{}, {}]",
    "x = {} + {}",
    "x = [{} for i in L]",
    "x = {}[0]",
    "x = {}[1:3]",
    "x = {{'k': {}}}",
]


def expression(rng: random.Random, depth: int = 0) -> str:
    roll = rng.random()
    if depth > 3 or roll < 0.35:
        return rng.choice(ATOMS + NAMES)
    if roll < 0.55:
        return "[" + ", ".join(expression(rng, depth + 1) for _ in range(rng.randint(0, 5))) + "]"
    if roll < 0.7:
        op = rng.choice(["+", "-", "*", "/", "<", "=="])
        return f"({expression(rng, depth + 1)} {op} {expression(rng, depth + 1)})"
    if roll < 0.8:
        return f"[{expression(rng, depth + 1)} for i in {rng.choice(NAMES)}]"
    if roll < 0.9:
        index = rng.choice(INDEXES)
        return f"{rng.choice(NAMES)}[{index}]"
    return f"f'<{{{rng.choice(NAMES)}}}>'"  # 3.11 f-strings cannot reuse the quote: only names inside


def program(rng: random.Random) -> str:
    lines = ["a = 1", "b = [2.0, 3.0]", "c = 'c'", "L = [0, 1, 2, 3]", "S = 'abc'"]
    lines.append("P = navigator.getPoseStamped([0.0, 3.0], 0)")
    for _ in range(rng.randint(1, 25)):
        roll = rng.random()
        if roll < 0.5:
            name = rng.choice(NAMES)
            parts = ", ".join([rng.choice(NAMES)] * rng.randint(1, 6))
            lines.append(f"{name} = [{parts}]" if roll < 0.25 else f"{name} = {expression(rng)}")
        else:
            sink = rng.choice(SINKS)
            lines.append(sink.format(*(expression(rng) for _ in range(sink.count("{}")))))
        if rng.random() < 0.2:
            lines.append(f"navigator.warn(f'value {{{rng.choice(NAMES)}}}')")
    return "\n".join(lines)


@pytest.mark.parametrize("seed", range(40))
def test_random_programs_plan_or_are_refused_briefly(seed, depot_context) -> None:
    table, check = depot_context
    rng = random.Random(seed)
    for _ in range(25):
        source = program(rng)
        started = time.thread_time()
        try:
            result = plan_program(source, table, check)
        except ProgramRejected as refusal:
            assert 0 < len(str(refusal)) <= 320, source
        except PlanningError as error:  # pragma: no cover - the failure message is the point
            pytest.fail(f"planner error {error} on:\n{source}")
        else:
            assert isinstance(result, Plan)
            assert all(len(step.describe()) <= 210 for step in result.steps)
        assert time.thread_time() - started < 1.0, source
