"""Benchmark of a fleet in one world: real-time factor with 1, 3, 10 and 20 robots, every robot navigating with
the whole core stack (AMCL, costmaps, planner, controller), stepped in one loop in-process. Beside it, in the same
run, the one-robot baseline: a plain Simulation + NavigationCore stepped the same way (no fleet).

Each robot starts on a free spot of the warehouse's open floor and drives to random free goals (a new one when a
goal ends), seeded, so every run does the same work.

    python bench/bench_fleet.py [--quick]
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.nav.server import NavigationCore  # noqa: E402
from tb4.sim.fleet import Fleet, robot_nav_seed  # noqa: E402
from tb4.sim.fleet_spec import RobotSpec  # noqa: E402
from tb4.sim.simulation import Simulation  # noqa: E402
from tb4.sim.world import World, load_world  # noqa: E402

__all__ = ["run", "fleet_rtf", "single_rtf"]

SIZES = (1, 3, 10, 20)
CONTROL_STEPS = 5  # physics steps per control tick (0.05 s), as the simulator loop does


def start_poses(world: World, count: int) -> list[tuple[float, float, float]]:
    """`count` free spots on a 1 m grid around the dock (clear of walls and obstacles by 0.5 m)."""
    sim = Simulation.from_world(world)
    out = []
    for ring in range(1, 12):
        for ix in range(-ring, ring + 1):
            for iy in range(-ring, ring + 1):
                if max(abs(ix), abs(iy)) != ring or len(out) >= count:
                    continue
                x, y = -1.0 - ix * 1.0, iy * 1.0
                if sim.clearance_at(x, y) > 0.5:
                    out.append((x, y, 0.0))
    if len(out) < count:
        raise RuntimeError(f"only {len(out)} free start spots near the dock for {count} robots")
    return out


def goal_pool(world: World, rng: np.random.Generator, count: int = 200) -> list[tuple[float, float, float]]:
    """Free goals (clearance > 0.6 m) anywhere on the map, seeded."""
    field = Simulation.from_world(world).field
    free = np.argwhere(field.dist > 0.6)
    pick = free[rng.integers(len(free), size=count)]
    return [
        (field.origin_x + (c + 0.5) * field.resolution, field.origin_y + (r + 0.5) * field.resolution, 0.0)
        for r, c in pick
    ]


def _drive(sims: list[Simulation], navs: list[NavigationCore], step, goals, seconds: float) -> float:
    """Step everything `seconds` of sim time with a goal always running on every robot; the wall time."""
    tasks: list = [None] * len(sims)
    rng = np.random.default_rng(11)
    t_end = sims[0].time + seconds
    w0 = time.perf_counter()
    while sims[0].time < t_end:
        for i, nav in enumerate(navs):
            if tasks[i] is None or tasks[i].done:
                tasks[i] = nav.start_navigate_to_pose(goals[int(rng.integers(len(goals)))])
        step(CONTROL_STEPS)
        now = sims[0].time
        for nav in navs:
            nav.step(now)
    return time.perf_counter() - w0


def fleet_rtf(world: World, count: int, seconds: float, goals) -> float:
    poses = start_poses(world, count)
    specs = [RobotSpec(f"/robot{k + 1}", pose, world.dock) for k, pose in enumerate(poses)]
    fleet = Fleet(world, specs, seed=0, odom_noise=True, lidar_noise=True)
    sims = list(fleet)
    navs = [
        NavigationCore(world.map, robot=s, localization="amcl", seed=robot_nav_seed(0, k)) for k, s in enumerate(sims)
    ]
    for nav, pose in zip(navs, poses, strict=True):
        nav.set_initial_pose(*pose)
    return seconds / _drive(sims, navs, fleet.step, goals, seconds)


def single_rtf(world: World, seconds: float, goals) -> float:
    """The one-robot baseline: no fleet, the same loop."""
    pose = start_poses(world, 1)[0]
    sim = Simulation(
        world.map,
        world.dock,
        pose,
        world.obstacles,
        static_mask=world.static_obstacle_mask(),
        odom_noise=True,
        lidar_noise=True,
    )
    nav = NavigationCore(world.map, robot=sim, localization="amcl", seed=0)
    nav.set_initial_pose(*pose)
    return seconds / _drive([sim], [nav], sim.step, goals, seconds)


def run(quick: bool = False) -> list[dict]:
    """Rows {name, ours, baseline, unit, ratio, goal} for the bench runner."""
    world = load_world("warehouse")
    goals = goal_pool(world, np.random.default_rng(3))
    seconds = 10.0 if quick else 30.0
    base = single_rtf(world, seconds, goals)
    rows = []
    for count in SIZES:
        rtf = fleet_rtf(world, count, seconds, goals)
        rows.append(
            {
                "name": f"fleet of {count} navigating (AMCL) in one loop: RTF",
                "ours": rtf,
                "baseline": base,
                "baseline_name": "one robot, no fleet, same loop",
                "unit": "x",
                "ratio": rtf / base,
                "goal": ">= 10x" if count == 10 else "-",
            }
        )
        if math.isfinite(rtf) and rtf < 1.0:
            break  # slower than real time: bigger fleets only take longer
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv[1:]):
        print(f"{row['name']:<52} {row['ours']:>8.1f} x   one robot {row['baseline']:>8.1f} x   {row['goal']}")
