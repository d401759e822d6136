"""Install and start-up figures: the no-change install, importing tb4, and the simulator's time to ready.

Cold install (a fresh clone, `make install` from nothing) takes minutes, so it runs only with TB4_BENCH_COLD=1. Its
baseline is measured in the same install: the step that installs the wheels (ROS 2, build tools, dependencies) from
the pip cache, which any install must do; the rest is what building our interfaces and kernels adds.
"""

from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402

__all__ = ["run", "cold_install"]


def _timed(args: list[str], cwd: Path = ROOT, env: dict[str, str] | None = None) -> float:
    start = time.monotonic()
    subprocess.run(args, cwd=cwd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - start


# tools/install.sh's closing summary: one "  SECONDS s  STEP" line per step; these are the wheels' (the wheel cache's
# fill or lookup, the build tools' pip, the wait for the second pip after the build)
WHEEL_STEPS = re.compile(
    r"^\s*([0-9.]+) s  (?:requirement wheels ready|ROS 2 build tools and message packages \(pip\)"
    r"|ROS 2 wheels and dependencies \(pip)",
    re.M,
)


def cold_install(clone: Path) -> tuple[float, float, str]:
    """(wall s of `make install` in a fresh clone, s of its wheel-install steps, its output)."""
    start = time.monotonic()
    proc = subprocess.run(["make", "install"], cwd=clone, capture_output=True, text=True, check=True)
    wall = time.monotonic() - start
    steps = [float(m) for m in WHEEL_STEPS.findall(proc.stdout)]
    if len(steps) < 2:
        raise RuntimeError(f"no wheel-install steps in the install's summary:\n{proc.stdout[-2000:]}")
    return wall, sum(steps), proc.stdout


def _median(args: list[str], n: int, env: dict[str, str] | None = None) -> float:
    return statistics.median(_timed(args, env=env) for _ in range(n))


def _sim_ready_time(env: dict[str, str]) -> float:
    start = time.monotonic()
    proc = ManagedProcess(
        tb4_command("sim", "--rate", "max"),
        env=env,
        log_path=Path(tempfile.mkstemp(suffix=".log")[1]),
    )
    try:
        if not proc.wait_for_output("tb4 sim ready", 60):
            raise RuntimeError(f"simulator did not start: {proc.output()[-500:]}")
        return time.monotonic() - start
    finally:
        proc.stop()


def run(quick: bool = False) -> list[dict]:
    n = 2 if quick else 5
    py = sys.executable
    env = ros_environment(claim_domain_id())
    rows = []
    make_noop = _median(["make", "install"], n)
    pip_noop = _timed([py, "-m", "pip", "install", "-q", "--no-build-isolation", "--no-deps", "-e", "."])
    rows.append(
        {
            "name": "install, nothing changed (make install)",
            "ours": make_noop,
            "baseline": pip_noop,
            "baseline_name": "pip install -e . rebuild",
            "unit": "s",
            "ratio": pip_noop / make_noop,
            "goal": "quick when already done",
        }
    )
    bare = _median([py, "-c", "pass"], n, env)
    tb4_import = _median([py, "-c", "import tb4"], n, env)
    rows.append(
        {
            "name": "python start + import tb4",
            "ours": tb4_import,
            "baseline": bare,
            "baseline_name": "python -c pass",
            "unit": "s",
            "ratio": bare / tb4_import,
            "goal": "no ROS import",
        }
    )
    node = _median([py, "-c", "import rclpy; rclpy.init(); rclpy.create_node('bench'); rclpy.shutdown()"], n, env)
    sim = statistics.median(_sim_ready_time(env) for _ in range(2 if quick else 3))
    rows.append(
        {
            "name": "tb4 sim: start to serving",
            "ours": sim,
            "baseline": node,
            "baseline_name": "bare rclpy node process",
            "unit": "s",
            "ratio": node / sim,
            "goal": "a few s",
        }
    )
    if os.environ.get("TB4_BENCH_COLD") == "1":
        with tempfile.TemporaryDirectory() as tmp:
            clone = Path(tmp) / "clone"
            subprocess.run(["git", "clone", "-q", str(ROOT), str(clone)], check=True)
            cold, wheels, _ = cold_install(clone)
        rows.append(
            {
                "name": "cold install (fresh clone, make install)",
                "ours": cold,
                "baseline": wheels,
                "baseline_name": "its wheel-install steps alone (wheel cache)",
                "unit": "s",
                "ratio": wheels / cold,
                "goal": "<= 120 s",
            }
        )
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)
