"""Benchmark of `tb4 sweep`: trials per minute of nav_to_pose over N seeds (200 by default), beside the baseline a
user would write, a shell loop of `tb4 run nav_to_pose --seed S --quiet`, measured in the same run; the sweep with a
new simulator per trial (`--new-simulators`, how every trial ran before simulators were reset between trials); and
the same sweep on the Ray backend, on a loopback Ray head of its own with as many CPUs as the local sweep has workers
(with the [cluster] extra), beside the local one. Every sweep runs with `tb4 sweep`'s default workers, as a user runs
it.

    python bench/bench_sweep.py [--seeds N] [--loop-seeds M] [--pairs K] [--quick] [--no-ray]

The loop and the --new-simulators sweep cost several seconds a trial: they are measured on the first M seeds of the
N (20 by default; --loop-seeds N for all of them) and their rates carried over to N, which the rows say. Each
measure runs alone, one after the other, on whatever else the machine runs: the figures of one run compare. With
--pairs K the sweep and its Ray twin run K times, alternately, and their rates are over all K.

The issue's goals: at least 5x the loop, 1,000 seeds in at most 10 minutes on a 2-core machine, and the Ray backend
within 15 % of the local one on one machine.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.processes import claim_domain_id, release_domain_id, ros_environment, tb4_command  # noqa: E402

__all__ = ["run", "loop_seconds", "sweep_seconds"]

MISSION = "nav_to_pose"


def loop_seconds(seeds: range, folder: Path) -> tuple[float, int]:
    """Wall seconds of `for S in seeds: tb4 run nav_to_pose --seed S --quiet`, and how many succeeded."""
    domain = claim_domain_id()
    env = ros_environment(domain)
    succeeded = 0
    start = time.perf_counter()
    try:
        for seed in seeds:
            done = subprocess.run(
                [*tb4_command("run", MISSION, "--seed", str(seed), "--quiet", "--output-dir", str(folder))],
                env=env,
                capture_output=True,
                timeout=600,
                stdin=subprocess.DEVNULL,
            )
            succeeded += done.returncode == 0
    finally:
        release_domain_id(domain)
    return time.perf_counter() - start, succeeded


def sweep_seconds(seeds: range, folder: Path, *options: str) -> tuple[float, int]:
    """Wall seconds of `tb4 sweep nav_to_pose --seeds A:B OPTIONS` (--ray: on a Ray head of its own;
    --new-simulators: a `tb4 run` per trial), and how many succeeded."""
    args = tb4_command("sweep", MISSION, "--seeds", f"{seeds.start}:{seeds.stop}", "--output", str(folder), "--json")
    args += list(options)
    start = time.perf_counter()
    done = subprocess.run(args, env=dict(os.environ), capture_output=True, text=True, timeout=7200)
    seconds = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise RuntimeError(f"tb4 sweep failed ({done.returncode}): {done.stderr[-2000:]}")
    rows = [json.loads(line) for line in done.stdout.splitlines() if '"event": "row"' in line]
    for row in rows:
        if row["outcome"] != "succeeded":  # a figure over trials that did not all succeed says why
            print(f"[bench sweep] {' '.join(options)} seed {row['seed']}: {row['reason']}", file=sys.stderr)
    return seconds, sum(row["outcome"] == "succeeded" for row in rows)


def run(
    quick: bool = False, seeds: int | None = None, loop_seeds: int | None = None, ray: bool = True, pairs: int = 1
) -> list[dict]:
    count = seeds or (10 if quick else 200)
    subset = min(count, loop_seeds or (5 if quick else 20))
    chosen, first = range(count), range(subset)
    on = f"{count} seeds" if subset == count else f"{subset} of the {count} seeds, carried over"
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="tb4-bench-sweep-") as tmp:
        folder = Path(tmp)
        loop, loop_ok = loop_seconds(first, folder / "loop")
        loop_per_minute = subset / loop * 60.0
        fresh, fresh_ok = sweep_seconds(first, folder / "fresh", "--new-simulators")
        fresh_per_minute = subset / fresh * 60.0
        ray = ray and _ray_installed()
        # the local and the Ray sweep one after the other, `pairs` times: a change of load on a shared machine
        # weighs on both
        sweep = ray_seconds = 0.0
        sweep_ok = ray_ok = 0
        for pair in range(max(1, pairs)):
            seconds, ok = sweep_seconds(chosen, folder / f"sweep-{pair}")  # its default workers, as a user runs it
            sweep, sweep_ok = sweep + seconds, sweep_ok + ok
            if ray:
                seconds, ok = sweep_seconds(chosen, folder / f"ray-{pair}", "--ray")  # a head of as many CPUs
                ray_seconds, ray_ok = ray_seconds + seconds, ray_ok + ok
        runs = count * max(1, pairs)
        per_minute = runs / sweep * 60.0
        rows.append(
            {
                "name": f"sweep of {MISSION}, {count} seeds, default workers "
                f"({sweep_ok}/{runs} succeeded; loop {loop_ok}/{subset})",
                "ours": per_minute,
                "unit": "trials/min",
                "baseline": loop_per_minute,
                "baseline_name": f"shell loop of tb4 run ({on})",
                "ratio": per_minute / loop_per_minute,
                "goal": ">= 5x",
            }
        )
        rows.append(
            {
                "name": f"the same sweep, a new simulator per trial ({fresh_ok}/{subset} succeeded)",
                "ours": per_minute,
                "unit": "trials/min",
                "baseline": fresh_per_minute,
                "baseline_name": f"tb4 sweep --new-simulators ({on})",
                "ratio": per_minute / fresh_per_minute,
                "goal": "",
            }
        )
        rows.append(
            {
                "name": f"1,000 seeds of {MISSION} at this rate",
                "ours": 1000.0 / per_minute,
                "unit": "min",
                "baseline": 1000.0 / loop_per_minute,
                "baseline_name": "shell loop",
                "ratio": (1000.0 / loop_per_minute) / (1000.0 / per_minute),
                "goal": "<= 10 min",
            }
        )
        if not ray:
            return rows
        ray_per_minute = runs / ray_seconds * 60.0
        rows.append(
            {
                "name": f"the same sweep on a local Ray head of as many CPUs ({ray_ok}/{runs} succeeded)",
                "ours": ray_per_minute,
                "unit": "trials/min",
                "baseline": per_minute,
                "baseline_name": "tb4 sweep, local workers",
                "ratio": ray_per_minute / per_minute,
                "goal": "within 15 % (>= 0.85x)",
            }
        )
    return rows


def _ray_installed() -> bool:
    try:
        import ray  # noqa: F401
    except ImportError:
        print("[bench sweep] Ray not installed ([cluster] extra): no Ray row", file=sys.stderr)
        return False
    return True


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=None, help="seeds of the sweep (default 200; --quick 10)")
    parser.add_argument(
        "--loop-seeds", type=int, default=None, help="seeds of the loop and --new-simulators (default 20; --quick 5)"
    )
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--no-ray", action="store_true", help="no Ray row")
    parser.add_argument(
        "--pairs", type=int, default=1, help="times the local and the Ray sweep run, one after the other (default 1)"
    )
    args = parser.parse_args()
    rows = run(quick=args.quick, seeds=args.seeds, loop_seeds=args.loop_seeds, ray=not args.no_ray, pairs=args.pairs)
    for row in rows:
        print(
            f"{row['name']}: {row['ours']:.3g} {row['unit']} vs {row['baseline']:.3g} ({row['baseline_name']}), "
            f"{row['ratio']:.2f}x, goal {row['goal']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
