"""Benchmark of the simulator core: real-time factor and lidar scan time, each beside a baseline run here.

The run drives the robot around the warehouse (100 Hz physics, 20 Hz commands from a simple reactive driver,
10 Hz 360-beam scans). The baseline lidar is a vectorised NumPy ray caster: all beams sampled every half cell
along the ray in one array operation, the first occupied sample per beam.

    python bench/bench_sim_core.py [--quick]
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.core.maps import OccupancyMap  # noqa: E402
from tb4.sim.simulation import Simulation  # noqa: E402

__all__ = ["run", "baseline_ranges", "build_simulation"]


def _synthetic_warehouse() -> tuple[OccupancyMap, tuple[float, float, float]]:
    """1006 x 1674 cells at 0.03 m: outer walls and rows of shelves, like the warehouse world."""
    res, h, w = 0.03, 1674, 1006
    data = np.zeros((h, w), dtype=np.int8)
    data[:4, :] = data[-4:, :] = 100
    data[:, :4] = data[:, -4:] = 100
    for row in range(150, 700, 90):  # south racks, rows along y
        data[row : row + 30, 60:450] = 100
        data[row : row + 30, 560:950] = 100
    for col in range(80, 950, 110):  # north racks, rows along x
        data[1000:1550, col : col + 30] = 100
    return OccupancyMap(data, res, -15.1, -25.0), (0.0, 0.0, 0.0)


def build_simulation() -> tuple[Simulation, str]:
    """The warehouse world when tb4.sim.world is available, else a synthetic map of the same size."""
    try:
        from tb4.sim.world import load_world

        world = load_world("warehouse")
        return Simulation.from_world(world), "warehouse world"
    except ImportError:
        grid, dock = _synthetic_warehouse()
        return Simulation(grid, dock, dock), "synthetic warehouse-sized map"


def baseline_ranges(
    mask: np.ndarray, res: float, ox: float, oy: float, x: float, y: float, yaw: float, beams: int, rmax: float
) -> np.ndarray:
    """Vectorised ray casting with NumPy: every beam sampled every half cell at once (one beams x samples
    array of cell lookups), the first occupied sample per beam (inf if none)."""
    h, w = mask.shape
    steps = np.arange(1, int(rmax / (0.5 * res)) + 1) * (0.5 * res)
    angles = yaw + 2.0 * math.pi * np.arange(beams) / beams
    cols = np.floor((x + np.cos(angles)[:, None] * steps - ox) / res).astype(np.intp)
    rows = np.floor((y + np.sin(angles)[:, None] * steps - oy) / res).astype(np.intp)
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    hits = np.zeros(cols.shape, dtype=bool)
    hits[inside] = mask[rows[inside], cols[inside]]
    first = hits.argmax(axis=1)
    return np.where(hits[np.arange(beams), first], steps[first], np.inf)


def _drive(sim: Simulation, seconds: float, lidar: str, mask: np.ndarray) -> float:
    """Drive for `seconds` of sim time; returns the wall time. `lidar` is 'ours' or 'baseline'."""
    p = sim.params.lidar
    g = sim.grid
    scan_every = round(1.0 / (p.rate_hz * sim.physics_dt))
    ctrl_every = round(0.05 / sim.physics_dt)
    front = np.r_[0:30, p.beams - 30 : p.beams]
    turn = 0.0
    ranges = np.full(p.beams, np.inf)
    steps = round(seconds / sim.physics_dt)
    t0 = time.perf_counter()
    for k in range(0, steps, ctrl_every):
        if k % scan_every == 0:
            if lidar == "ours":
                ranges = sim.scan().ranges
            else:
                pose = sim.pose()
                ranges = baseline_ranges(
                    mask, g.resolution, g.origin_x, g.origin_y, pose.x, pose.y, pose.yaw, p.beams, p.range_max
                )
        if np.min(ranges[front]) < 0.7:
            turn = turn or 1.2
            sim.set_velocity_command(0.0, turn)
        else:
            turn = 0.0
            sim.set_velocity_command(0.26, 0.3 * math.sin(sim.time / 3.0))
        sim.step(ctrl_every)
    return time.perf_counter() - t0


def _free_poses(sim: Simulation, n: int, rng: np.random.Generator) -> list[tuple[float, float, float]]:
    f = sim.field
    free = np.argwhere(f.dist > 0.4)
    pick = free[rng.integers(len(free), size=n)]
    return [
        (f.origin_x + (c + 0.5) * f.resolution, f.origin_y + (r + 0.5) * f.resolution, float(rng.uniform(-3, 3)))
        for r, c in pick
    ]


def run(quick: bool = False) -> list[dict]:
    """Rows {name, ours, baseline, unit, ratio, goal} for the bench runner."""
    sim, what = build_simulation()
    mask = sim.field.dist[sim.field.pad : -sim.field.pad, sim.field.pad : -sim.field.pad] <= 0.0
    start = (1.0, 1.0, math.pi / 2)
    p = sim.params.lidar
    g = sim.grid

    seconds = 20.0 if quick else 120.0
    sim.set_pose(*start)
    wall_ours = _drive(sim, seconds, "ours", mask)
    base_seconds = 2.0 if quick else 6.0
    sim.set_pose(*start)
    wall_base = _drive(sim, base_seconds, "baseline", mask)
    rtf_ours, rtf_base = seconds / wall_ours, base_seconds / wall_base

    poses = _free_poses(sim, 40 if quick else 200, np.random.default_rng(7))
    lidar = sim.lidar
    for pose in poses[:5]:
        lidar.ranges(*pose)
    t0 = time.perf_counter()
    ours = [lidar.ranges(*pose) for pose in poses]
    t_ours = (time.perf_counter() - t0) / len(poses)
    nb = min(len(poses), 10 if quick else 30)
    t0 = time.perf_counter()
    base = [
        baseline_ranges(mask, g.resolution, g.origin_x, g.origin_y, *pose, p.beams, p.range_max) for pose in poses[:nb]
    ]
    t_base = (time.perf_counter() - t0) / nb

    a, b = np.concatenate(ours[:nb]), np.concatenate(base)
    both = np.isfinite(a) & np.isfinite(b)
    agree = float(np.mean(np.abs(a[both] - b[both]) <= 2 * g.resolution)) if both.any() else 1.0
    same_hit = float(np.mean(np.isfinite(a) == np.isfinite(b)))
    print(
        f"# {what}: {g.width}x{g.height} cells at {g.resolution} m; {p.beams} beams; "
        f"{agree:.1%} of ranges within 2 cells of the baseline, {same_hit:.1%} same hit/no-hit"
    )
    return [
        {
            "name": "sim real-time factor (100 Hz physics, 10 Hz lidar, driving)",
            "ours": rtf_ours,
            "baseline": rtf_base,
            "unit": "x real time",
            "ratio": rtf_ours / rtf_base,
            "goal": ">= 300x",
        },
        {
            "name": f"lidar scan ({p.beams} beams, warehouse map)",
            "ours": t_ours * 1e3,
            "baseline": t_base * 1e3,
            "unit": "ms",
            "ratio": t_base / t_ours,
            "goal": "well under 1 ms",
        },
    ]


def _print(rows: list[dict]) -> None:
    print(f"{'figure':<62} {'ours':>10} {'baseline':>10} {'unit':<12} {'ratio':>8}  goal")
    for r in rows:
        print(
            f"{r['name']:<62} {r['ours']:>10.3f} {r['baseline']:>10.3f} {r['unit']:<12} "
            f"{r['ratio']:>7.1f}x  {r['goal']}"
        )


if __name__ == "__main__":
    _print(run(quick="--quick" in sys.argv[1:]))
