"""Benchmark: offline interpreter accuracy on the evaluation sets, beside exact-name matching, same run.

Run: `python bench/bench_language.py [--quick] [--verbose]`. Every command of src/tb4/language/eval_commands.yaml
(the upstream tutorial's examples and variations, plus commands that must be refused: the set the interpreter was
tuned on) and of eval_commands_heldout.yaml (written before the interpreter saw it, never tuned on) goes through
the interpreter and the safe executor's planner; it is right when the planned robot actions equal the expected
ones (or, for a command that must be refused, when no program comes out). The baseline understands exact names
only: "dock", "undock" and destination names as written in the world file. Also timed: planning a program in the
executor, and refusing every hostile program of the test suite (tests/core/language: HOSTILE and BOMBS), of which the
slowest and the most memory-hungry are reported beside a benign program.
"""

from __future__ import annotations

import statistics
import sys
import time
import tracemalloc
from pathlib import Path

try:
    import tb4  # noqa: F401
except ImportError:  # running from a checkout without the package installed
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

import contextlib

from tb4.language.evaluation import (
    HELDOUT_FILE,
    EvalCase,
    evaluate,
    exact_name_baseline,
    load_eval_set,
    offline_interpreter,
)
from tb4.language.executor import PlanningError, ProgramRejected, plan_program
from tb4.language.world_context import destination_table, pose_checker
from tb4.sim.world import load_world

__all__ = ["run", "main", "hostile_suite", "measure_refusal", "accuracy_row"]

WORLD = "depot"
BENIGN = (
    "poses = [navigator.getPoseStamped(destinations[n][0:2], destinations[n][2]) for n in ['wood crate', 'dock']]\n"
    "navigator.startFollowWaypoints(poses)\n"
    "navigator.info(f'visited {poses}')\n"
    "navigator.dock()\n"
)


def hostile_suite() -> list[tuple[str, str]]:
    """The hostile programs of the test suite, (id, program)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "core" / "language"))
    from test_language_budgets import BOMBS  # noqa: PLC0415 - the suite lives with the tests
    from test_language_executor import HOSTILE  # noqa: PLC0415

    return list(BOMBS) + list(HOSTILE)


def measure_refusal(program: str, table: dict, check, reps: int) -> tuple[float, float, str]:
    """(median seconds, peak traced bytes, outcome) of validating + planning `program`."""
    times = []
    outcome = "planned"
    for _ in range(reps):
        t0 = time.perf_counter()
        try:
            plan_program(program, table, check)
        except (ProgramRejected, PlanningError) as exc:
            outcome = type(exc).__name__
        times.append(time.perf_counter() - t0)
    tracemalloc.start()
    try:
        with contextlib.suppress(ProgramRejected, PlanningError):
            plan_program(program, table, check)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return statistics.median(times), float(peak), outcome


def accuracy_row(world, cases: list[EvalCase], which: str, show_wrong: bool) -> dict:
    """The interpreter's accuracy on `cases` beside exact-name matching's, as a bench row."""
    ours = evaluate(offline_interpreter(world), world, cases)
    base = evaluate(exact_name_baseline(world), world, cases)
    right, base_right = sum(r.correct for r in ours), sum(r.correct for r in base)
    acc_ours, acc_base = 100.0 * right / len(cases), 100.0 * base_right / len(cases)
    print(f"# offline interpreter, {which}: {right}/{len(cases)} commands right; exact-name baseline: {base_right}")
    for r in [r for r in ours if not r.correct] if show_wrong else []:
        print(f"#   wrong: {r.case.text!r}: expected {r.case.expect}, got {r.got} {r.note}".rstrip())
    return {
        "name": f"offline interpreter accuracy, {which} ({len(cases)} commands, depot)",
        "ours": acc_ours,
        "baseline": acc_base,
        "unit": "% right",
        "baseline_name": "exact names only",
        "ratio": acc_ours / acc_base if acc_base else float("inf"),
        "goal": ">= 90% (baseline: exact names only)",
    }


def run(quick: bool = False, verbose: bool = False) -> list[dict]:
    """Rows {name, ours, baseline, unit, ratio, goal} for the bench runner."""
    world = load_world(WORLD)
    cases = load_eval_set()
    show_wrong = verbose or not quick
    accuracy = [
        accuracy_row(world, cases, "tuning set", show_wrong),
        accuracy_row(world, load_eval_set(HELDOUT_FILE), "held-out set", show_wrong),
    ]

    interpret = offline_interpreter(world)
    programs = [p for p in (interpret(c.text) for c in cases) if p]
    table, check = destination_table(world), pose_checker(world)
    reps = 3 if quick else 20
    for program in programs:  # warm-up: first calls pay for imports and caches
        plan_program(program, table, check)
    t0 = time.perf_counter()
    for _ in range(reps):
        for program in programs:
            plan_program(program, table, check)
    t_plan = (time.perf_counter() - t0) / (reps * len(programs))
    t0 = time.perf_counter()
    for _ in range(reps):
        for program in programs:
            compile(program, "<program>", "exec")  # what upstream does before exec(), with no checks at all
    t_compile = (time.perf_counter() - t0) / (reps * len(programs))
    suite = hostile_suite()
    hostile = {ident: measure_refusal(p, table, check, 3 if quick else 9) for ident, p in suite}
    benign = measure_refusal(BENIGN, table, check, 3 if quick else 9)
    slowest = max(hostile, key=lambda k: hostile[k][0])
    hungriest = max(hostile, key=lambda k: hostile[k][1])
    not_refused = [k for k, v in hostile.items() if v[2] == "planned"]
    print(
        f"# hostile suite: {len(suite)} programs, {len(suite) - len(not_refused)} refused; "
        f"slowest {slowest} {hostile[slowest][0] * 1e3:.1f} ms, "
        f"most memory {hungriest} {hostile[hungriest][1] / 1e6:.2f} MB"
    )
    issue = hostile.get("shared-info")
    if issue is not None:
        print(f"# the issue's 560-character program (A20 = 4**21 shared leaves): {issue[0] * 1e3:.1f} ms, {issue[2]}")
    if not_refused:
        print(f"#   NOT refused: {', '.join(not_refused)}")
    return [
        {
            "name": f"hostile programs refused ({len(suite)} in the test suite)",
            "ours": 100.0 * (len(suite) - len(not_refused)) / len(suite),
            "baseline": None,
            "unit": "%",
            "goal": "100 %",
        },
        {
            "name": f"validate + plan the slowest hostile program ({slowest})",
            "ours": hostile[slowest][0] * 1e3,
            "baseline": benign[0] * 1e3,
            "unit": "ms",
            "baseline_name": "a benign 4-step program",
            "ratio": hostile[slowest][0] / benign[0],
            "goal": "< 1000 ms (issue: refused within 1 s)",
        },
        {
            "name": f"peak memory planning the hungriest hostile program ({hungriest})",
            "ours": hostile[hungriest][1] / 1e6,
            "baseline": benign[1] / 1e6,
            "unit": "MB",
            "baseline_name": "a benign 4-step program",
            "ratio": hostile[hungriest][1] / benign[1],
            "goal": "< 50 MB (issue)",
        },
        *accuracy,
        {
            "name": "check + plan one program (baseline: bare compile())",
            "ours": t_plan * 1e3,
            "baseline": t_compile * 1e3,
            "unit": "ms",
            "baseline_name": "bare compile(), what upstream runs before exec()",
            "ratio": t_compile / t_plan,
            "goal": "< 5 ms (negligible next to a drive)",
        },
    ]


def _print(rows: list[dict]) -> None:
    print(f"{'figure':<80} {'ours':>10} {'baseline':>10} {'unit':<6} {'ratio':>8}  goal")
    for r in rows:
        base = f"{r['baseline']:>10.3f}" if r.get("baseline") is not None else f"{'-':>10}"
        ratio = f"{r['ratio']:>7.2f}x" if r.get("ratio") is not None else f"{'-':>8}"
        print(f"{r['name']:<80} {r['ours']:>10.3f} {base} {r['unit']:<6} {ratio}  {r['goal']}")


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    _print(run(quick="--quick" in args, verbose="--verbose" in args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
