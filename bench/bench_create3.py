"""Cost of the Create 3 base in the simulator core, each figure beside a baseline measured in the same run.

- physics step in the depot (which has a cliff) with the Create 3 base (safety, hazards, sensors) against the
  same simulation with the base's per-step hooks replaced by no-ops;
- the 7 IR intensities (sphere tracing along each beam) against one 360-beam lidar scan at the same poses;
- the bumper-zone probe against one full collision-checked physics step.

    python bench/bench_create3.py [--quick]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.sim.hazards import contact_angle  # noqa: E402
from tb4.sim.simulation import Simulation  # noqa: E402
from tb4.sim.world import load_world  # noqa: E402

__all__ = ["run"]


def _drive(sim: Simulation, steps: int) -> float:
    """Seconds of wall time per physics step, driving arcs in the open depot floor."""
    sim.set_pose(-6.0, -1.0, 0.0)
    t0 = time.perf_counter()
    for i in range(steps):
        if i % 5 == 0:
            sim.set_velocity_command(0.2, 0.4 if (i // 400) % 2 else -0.4)
        sim.step()
    return (time.perf_counter() - t0) / steps


def _without_base(sim: Simulation) -> Simulation:
    base = sim.base
    base.gate = lambda _sim, v, w, builtin, exempt: (v, w, "")  # type: ignore[method-assign]
    base.after_move = lambda *args, **kwargs: ""  # type: ignore[method-assign]
    return sim


def run(quick: bool = False) -> list[dict]:
    world = load_world("depot")
    steps = 4000 if quick else 20000
    ours = min(_drive(Simulation.from_world(world), steps) for _ in range(3))
    bare = min(_drive(_without_base(Simulation.from_world(world)), steps) for _ in range(3))

    sim = Simulation.from_world(world)
    poses = [(-6.0 + 0.1 * k, -1.0 + 0.05 * (k % 7), 0.3 * k) for k in range(40)]
    t0 = time.perf_counter()
    for x, y, yaw in poses:
        sim.set_pose(x, y, yaw)
        sim.base.ir(sim)
    t_ir = (time.perf_counter() - t0) / len(poses)
    t0 = time.perf_counter()
    for x, y, yaw in poses:
        sim.lidar.ranges(x, y, yaw)
    t_scan = (time.perf_counter() - t0) / len(poses)

    radius = sim.params.drive.radius
    t0 = time.perf_counter()
    for x, y, yaw in poses:
        contact_angle(x, y, yaw, sim.clearance_at, radius)
    t_probe = (time.perf_counter() - t0) / len(poses)
    return [
        {"name": "physics step, Create 3 base on", "ours": ours * 1e6, "baseline": bare * 1e6,
         "baseline_name": "base hooks off", "unit": "us", "ratio": ours / bare, "goal": "within 2 us"},
        {"name": "7 IR intensities", "ours": t_ir * 1e6, "baseline": t_scan * 1e6,
         "baseline_name": "one 360-beam scan", "unit": "us", "ratio": t_ir / t_scan, "goal": "below a scan"},
        {"name": "bumper zone probe", "ours": t_probe * 1e6, "baseline": ours * 1e6,
         "baseline_name": "one physics step", "unit": "us", "ratio": t_probe / ours, "goal": "read at 20 Hz only"},
    ]  # fmt: skip


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(f"{row['name']}: {row['ours']:.1f} {row['unit']} (baseline {row['baseline_name']}: "
              f"{row['baseline']:.1f} {row['unit']})")  # fmt: skip
