"""Benchmark of `tb4 sweep`: trials per minute of nav_to_pose over N seeds, beside the baseline a user would write,
a shell loop of `tb4 run nav_to_pose --seed S --quiet` over the same seeds, measured in the same run; and the Ray
backend on a loopback Ray head of its own over the same seeds (with the [cluster] extra).

    python bench/bench_sweep.py [--seeds N] [--quick]

The issue's goals: at least 5x the loop, 1,000 seeds in at most 10 minutes on a 2-core machine, and the Ray backend
within 15 % of the local one on one machine.
"""

from __future__ import annotations

import argparse
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


def sweep_seconds(seeds: range, folder: Path, ray: bool = False) -> tuple[float, int]:
    """Wall seconds of `tb4 sweep nav_to_pose --seeds A:B` (with `--ray`: on a Ray head of its own), and how many
    succeeded."""
    args = tb4_command("sweep", MISSION, "--seeds", f"{seeds.start}:{seeds.stop}", "--output", str(folder), "--json")
    if ray:
        args.append("--ray")
    start = time.perf_counter()
    done = subprocess.run(args, env=dict(os.environ), capture_output=True, text=True, timeout=7200)
    seconds = time.perf_counter() - start
    if done.returncode not in (0, 1):
        raise RuntimeError(f"tb4 sweep failed ({done.returncode}): {done.stderr[-2000:]}")
    rows = [line for line in done.stdout.splitlines() if '"event": "row"' in line]
    return seconds, sum('"outcome": "succeeded"' in line for line in rows)


def run(quick: bool = False, seeds: int | None = None) -> list[dict]:
    count = seeds or (10 if quick else 200)
    chosen = range(count)
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="tb4-bench-sweep-") as tmp:
        folder = Path(tmp)
        loop, loop_ok = loop_seconds(chosen, folder / "loop")
        sweep, sweep_ok = sweep_seconds(chosen, folder / "sweep")
        per_minute = count / sweep * 60.0
        loop_per_minute = count / loop * 60.0
        rows.append(
            {
                "name": f"sweep of {MISSION}, {count} seeds ({sweep_ok} succeeded; loop {loop_ok})",
                "ours": per_minute,
                "unit": "trials/min",
                "baseline": loop_per_minute,
                "baseline_name": "shell loop of tb4 run",
                "ratio": per_minute / loop_per_minute,
                "goal": ">= 5x",
            }
        )
        rows.append(
            {
                "name": f"1,000 seeds of {MISSION} at this rate",
                "ours": 1000.0 / per_minute,
                "unit": "min",
                "baseline": 1000.0 / loop_per_minute,
                "baseline_name": "shell loop",
                "ratio": loop_per_minute and (1000.0 / loop_per_minute) / (1000.0 / per_minute),
                "goal": "<= 10 min",
            }
        )
        try:
            import ray  # noqa: F401
        except ImportError:
            print("[bench sweep] Ray not installed ([cluster] extra): no Ray row", file=sys.stderr)
            return rows
        ray_seconds, ray_ok = sweep_seconds(chosen, folder / "ray", ray=True)
        ray_per_minute = count / ray_seconds * 60.0
        rows.append(
            {
                "name": f"sweep on a local Ray head, {count} seeds ({ray_ok} succeeded)",
                "ours": ray_per_minute,
                "unit": "trials/min",
                "baseline": per_minute,
                "baseline_name": "tb4 sweep, local workers",
                "ratio": ray_per_minute / per_minute,
                "goal": "within 15 % (>= 0.85x)",
            }
        )
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=None, help="seeds per measure (default 200; --quick 10)")
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    for row in run(quick=args.quick, seeds=args.seeds):
        print(
            f"{row['name']}: {row['ours']:.3g} {row['unit']} vs {row['baseline']:.3g} ({row['baseline_name']}), "
            f"{row['ratio']:.2f}x, goal {row['goal']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
