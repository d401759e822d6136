"""A world reset (SimLoop.reset: Simulation.reset + NavigationCore.reset) gives the world a freshly built simulator
has for the same seed: the same inputs at the same ticks give the same run, bit for bit (no DDS involved)."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from tb4.nav.server import NavigationCore
from tb4.ros.loop import SimLoop
from tb4.sim.simulation import Simulation
from tb4.sim.world import load_world

WORLD = "warehouse"


def _fresh(seed: int, hold: bool = False) -> SimLoop:
    """What `tb4 sim --seed SEED` builds for one robot (noise on, AMCL)."""
    world = load_world(WORLD)
    sim = Simulation.from_world(world, seed=seed, odom_noise=True, lidar_noise=True)
    nav = NavigationCore(world.map, robot=sim, localization="amcl", seed=seed)
    return SimLoop(sim, nav, rate=float("inf"), hold=hold)


def _mission(loop: SimLoop, ticks: int = 600) -> list[tuple]:
    """A mission's inputs at fixed ticks (undock, initial pose, a goal across the warehouse), and every tick's
    state: the true pose and velocity, odometry, the localizer's estimate, the battery, the scan and the task."""
    states: list[tuple] = []
    for k in range(ticks):
        if k == 2:
            loop.sim.start_undock()
        if k == 3:
            loop.nav.set_initial_pose(0.0, 0.0, 0.0)
        if k == 120:
            loop.nav.start_navigate_to_pose((-6.0, 4.0, 0.0))
        loop.tick()
        pose, odom, scan = loop.sim.pose(), loop.sim.odometry(), loop.sim.scan()
        task = loop.nav.task
        states.append(
            (
                loop.sim.time,
                pose.x,
                pose.y,
                pose.yaw,
                odom.x,
                odom.y,
                odom.yaw,
                loop.nav.pose(),
                loop.sim.battery().percentage,
                hashlib.sha1(np.asarray(scan.ranges, dtype=np.float64).tobytes()).hexdigest(),
                None if task is None else (task.status, getattr(task, "number_of_recoveries", None)),
            )
        )
    return states


def test_a_reset_world_runs_bit_for_bit_as_a_fresh_one_for_the_same_seed() -> None:
    expected = _mission(_fresh(seed=7))
    assert expected[-1][1:3] != expected[0][1:3]  # the robot went somewhere: the comparison has something to compare
    used = _fresh(seed=3)
    _mission(used, ticks=300)  # another seed's run, stopped in the middle of its goal
    assert used.nav.active
    used.reset(7)
    assert used.sim.time == 0.0 and used.nav.task is None and not used.nav.localizer.is_localized
    assert _mission(used) == expected


def test_a_reset_ends_a_running_goal_and_a_watcher_hears_of_it() -> None:
    loop = _fresh(seed=1)
    _mission(loop, ticks=200)
    task = loop.nav.task
    finished = loop.watch(task)
    assert not finished.is_set()
    loop.reset(2)
    assert finished.is_set() and task.done and task.status == "canceled"


def test_a_reset_starts_the_timers_and_the_start_up_hold_again() -> None:
    loop = _fresh(seed=1, hold=True)
    stamps: list[float] = []
    loop.every(0.5, stamps.append)
    resets: list[int] = []
    loop.on_reset(lambda: resets.append(1))
    loop.release()
    for _ in range(40):
        loop.tick()
    assert not loop.held and stamps[-1] == pytest.approx(2.0)
    loop.reset(1)
    stamps.clear()
    for _ in range(20):
        loop.tick()
    assert loop.held and resets == [1]
    fresh = _fresh(seed=1, hold=True)
    fresh_stamps: list[float] = []
    fresh.every(0.5, fresh_stamps.append)
    for _ in range(20):
        fresh.tick()
    assert stamps == fresh_stamps == pytest.approx([0.05, 0.5, 1.0])  # from 0 again, as a new loop's


def test_a_reset_costmap_takes_the_maps_static_layers_again_and_a_loaded_map_does_not_stick() -> None:
    """A reset's global costmap takes the static layer and inflation built from the same map (read only since), not
    a resampling and inflation of it again; after a LoadMap it goes back to the map the core was built with."""
    loop = _fresh(seed=1)
    nav = loop.nav
    built = nav.global_costmap
    loop.reset(2)
    assert nav.global_costmap is not built  # a fresh costmap ...
    assert nav.global_costmap.static is built.static  # ... on the same layers
    assert np.array_equal(nav.global_costmap.costmap.data, built.costmap.data)

    other = load_world("depot").map
    nav.set_map(other)
    assert nav.global_costmap.layers.grid is other
    loop.reset(3)
    assert nav.global_costmap.static is built.static  # the built map's, not the loaded one's


def test_costmap_layers_built_with_other_parameters_are_built_anew() -> None:
    from dataclasses import replace

    from tb4.nav.costmap import GlobalCostmap

    grid = load_world(WORLD).map
    first = GlobalCostmap(grid)
    wider = replace(first.params, inflation_radius=first.params.inflation_radius + 0.2)
    again = GlobalCostmap(grid, wider, first.layers)
    assert again.static is not first.static and not np.array_equal(again.costmap.data, first.costmap.data)
    assert GlobalCostmap(grid, first.params, first.layers).static is first.static
