"""Benchmark: offline interpreter accuracy on the evaluation set, beside exact-name matching, same run.

Run: `python bench/bench_language.py [--quick] [--verbose]`. Every command of src/tb4/language/eval_commands.yaml
(the upstream tutorial's examples and variations, plus commands that must be refused) goes through the interpreter
and the safe executor's planner; it is right when the planned robot actions equal the expected ones (or, for a
command that must be refused, when no program comes out). The baseline understands exact names only: "dock",
"undock" and destination names as written in the world file. Also timed: planning a program in the executor.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

try:
    import tb4  # noqa: F401
except ImportError:  # running from a checkout without the package installed
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))

from tb4.language.evaluation import evaluate, exact_name_baseline, load_eval_set, offline_interpreter
from tb4.language.executor import plan_program
from tb4.language.world_context import destination_table, pose_checker
from tb4.sim.world import load_world

__all__ = ["run", "main"]

WORLD = "depot"


def run(quick: bool = False, verbose: bool = False) -> list[dict]:
    """Rows {name, ours, baseline, unit, ratio, goal} for the bench runner."""
    world = load_world(WORLD)
    cases = load_eval_set()
    ours = evaluate(offline_interpreter(world), world, cases)
    base = evaluate(exact_name_baseline(world), world, cases)
    acc_ours = 100.0 * sum(r.correct for r in ours) / len(cases)
    acc_base = 100.0 * sum(r.correct for r in base) / len(cases)
    wrong = [r for r in ours if not r.correct]
    print(
        f"# offline interpreter: {sum(r.correct for r in ours)}/{len(cases)} commands right; "
        f"exact-name baseline: {sum(r.correct for r in base)}/{len(cases)}"
    )
    for r in wrong if verbose or not quick else []:
        print(f"#   wrong: {r.case.text!r}: expected {r.case.expect}, got {r.got} {r.note}".rstrip())

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
    return [
        {
            "name": f"offline interpreter accuracy ({len(cases)} commands, depot)",
            "ours": acc_ours,
            "baseline": acc_base,
            "unit": "% right",
            "baseline_name": "exact names only",
            "ratio": acc_ours / acc_base if acc_base else float("inf"),
            "goal": ">= 90% (baseline: exact names only)",
        },
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
    print(f"{'figure':<62} {'ours':>10} {'baseline':>10} {'unit':<12} {'ratio':>8}  goal")
    for r in rows:
        print(
            f"{r['name']:<62} {r['ours']:>10.3f} {r['baseline']:>10.3f} {r['unit']:<12} "
            f"{r['ratio']:>7.2f}x  {r['goal']}"
        )


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    _print(run(quick="--quick" in args, verbose="--verbose" in args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
