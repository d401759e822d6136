"""The simulator loop survives failing publishers and tells watchers when tasks end (no DDS involved)."""

from __future__ import annotations

import math
import threading
import time

from tb4.nav.server import NavigationCore
from tb4.ros.loop import IDLE_TICK_LIMIT, WAITING_RATE, SimLoop
from tb4.sim.fleet import Fleet
from tb4.sim.fleet_spec import robots_on_docks
from tb4.sim.simulation import Simulation
from tb4.sim.world import load_world


def _loop() -> SimLoop:
    world = load_world("maze")
    sim = Simulation.from_world(world)
    return SimLoop(sim, NavigationCore(world.map, robot=sim), rate=float("inf"))


def test_a_failing_publisher_is_reported_and_the_loop_goes_on() -> None:
    loop = _loop()
    reports: list[str] = []
    loop.report = reports.append
    calls = {"good": 0}

    def broken(_now: float) -> None:
        raise RuntimeError("Failed to publish: cannot publish data")

    def good(_now: float) -> None:
        calls["good"] += 1

    loop.every(0.05, broken)
    loop.every(0.05, good)
    for _ in range(20):
        loop.tick()
    assert loop.publish_errors == 20 and calls["good"] == 20
    assert reports and "cannot publish data" in reports[0]
    assert loop.sim.time > 0.9


def test_watchers_are_told_when_a_task_ends_and_when_the_loop_stops() -> None:
    loop = _loop()
    loop.nav.set_initial_pose(0.0, 0.0, 0.0)
    task = loop.nav.start_wait(0.2)
    event = loop.watch(task)
    assert not event.is_set()
    for _ in range(10):
        loop.tick()
    assert event.is_set() and task.status == "succeeded"
    pending = loop.watch(loop.nav.start_wait(100.0))
    loop.start()
    loop.stop()
    assert pending.wait(2.0)
    assert isinstance(pending, threading.Event)


# --- idle ticks taken together at --rate max (SimLoop.idle_periods) -----------------------------------------------
def _docked_loop(world_name: str = "warehouse") -> SimLoop:
    world = load_world(world_name)
    sim = Simulation.from_world(world, battery_level=0.2)  # on its dock: charging
    return SimLoop(sim, NavigationCore(world.map, robot=sim), rate=float("inf"))


def _state(loop: SimLoop) -> tuple:
    sim = loop.sim
    return (sim.time, sim.steps, sim.pose(), sim.battery(), sim.odometry())


def test_a_robot_charging_on_its_dock_takes_a_second_per_tick_and_ends_in_the_same_state() -> None:
    """Bit for bit: the same pose, odometry and battery as one control period at a time (moving obstacles pass by
    in the warehouse; the loop takes smaller spans while one could reach the robot)."""
    fast, plain = _docked_loop(), _docked_loop()
    ticks = 0
    while fast.sim.time < 300.0:
        fast.tick(fast_forward=True)
        ticks += 1
    while plain.sim.steps < fast.sim.steps:
        plain.tick()
    assert _state(fast) == _state(plain)
    assert fast.sim.battery().percentage > 0.2  # it charged
    assert ticks <= 300.0 / IDLE_TICK_LIMIT * 1.5, ticks  # mostly whole seconds, not 6,000 ticks of 0.05 s
    assert fast.idle_periods() == round(IDLE_TICK_LIMIT / fast.control_period)


def test_a_periodic_job_runs_once_per_idle_tick_at_the_time_it_ends() -> None:
    loop = _docked_loop("maze")  # no moving obstacles
    seen: list[float] = []
    loop.every(0.05, seen.append)
    loop.tick()  # the robot settles on the dock
    loop.tick()
    seen.clear()
    for _ in range(3):
        loop.tick(fast_forward=True)
    assert seen == [loop.sim.time - 2 * IDLE_TICK_LIMIT, loop.sim.time - IDLE_TICK_LIMIT, loop.sim.time]


def test_nothing_is_taken_together_while_a_task_a_side_task_or_a_command_runs() -> None:
    loop = _docked_loop("maze")
    for _ in range(3):
        loop.tick()
    assert loop.idle_periods() > 1
    busy = {"side task": True}
    loop.busy_while(lambda: busy["side task"])
    assert loop.idle_periods() == 1
    busy["side task"] = False
    task = loop.nav.start_wait(5.0)  # a motion task (Nav2's Wait behavior)
    assert loop.idle_periods() == 1
    before = loop.sim.steps
    loop.tick(fast_forward=True)
    assert loop.sim.steps - before == loop.steps_per_tick
    task.cancel()
    loop.tick()
    loop.sim.set_velocity_command(0.1, 0.0)  # a velocity command (cmd_vel)
    loop.tick(fast_forward=True)
    assert loop.idle_periods() == 1


def test_a_request_submitted_during_an_idle_stretch_is_served_at_the_next_tick() -> None:
    loop = _docked_loop("maze")
    for _ in range(3):
        loop.tick()
    future = loop.submit(lambda: loop.nav.start_wait(1.0))
    loop.tick(fast_forward=True)  # served first: the task then keeps this tick to one period
    assert future.result(0).status == "running"
    assert loop.idle_periods() == 1


def test_a_robot_standing_still_away_from_its_dock_keeps_the_usual_ticks() -> None:
    """Between two commands of a script the loop must not put minutes of sim time."""
    loop = _docked_loop("maze")
    x, y, yaw = loop.sim.dock_pose
    loop.sim.set_pose(x - 1.0 * math.cos(yaw), y - 1.0 * math.sin(yaw), yaw)  # a metre in front of the dock
    for _ in range(3):
        loop.tick()
    assert not loop.sim.is_docked() and loop.sim.still_steps(100) == 100  # at rest, yet
    assert loop.idle_periods() == 1


# --- the pace at --rate max while every robot waits for a command (SimLoop.waiting) -------------------------------
def _waiting_loop(rate: float = math.inf, battery_level: float = 1.0) -> SimLoop:
    """The maze (no moving obstacles), the robot a metre in front of its dock, settled."""
    world = load_world("maze")
    sim = Simulation.from_world(world, battery_level=battery_level)
    loop = SimLoop(sim, NavigationCore(world.map, robot=sim), rate=rate)
    x, y, yaw = sim.dock_pose
    sim.set_pose(x - math.cos(yaw), y - math.sin(yaw), yaw)
    for _ in range(3):
        loop.tick()
    return loop


def test_a_waiting_robot_paces_max_at_the_waiting_rate_and_anything_it_does_lifts_that() -> None:
    loop = _waiting_loop()
    assert loop.waiting() and loop.pace() == WAITING_RATE
    loop.sim.set_velocity_command(0.1, 0.0)  # cmd_vel
    assert not loop.waiting() and loop.pace() == math.inf
    for _ in range(40):  # stops 0.5 s after the last command, then settles
        loop.tick()
    assert loop.pace() == WAITING_RATE
    task = loop.nav.start_wait(5.0)  # a motion task (Nav2's Wait behavior)
    assert loop.pace() == math.inf
    task.cancel()
    loop.tick()
    assert loop.pace() == WAITING_RATE
    busy = {"side task": True}
    loop.busy_while(lambda: busy["side task"])
    assert loop.pace() == math.inf
    busy["side task"] = False
    assert loop.pace() == WAITING_RATE


def test_a_charge_is_no_wait_a_full_battery_on_the_dock_is() -> None:
    charging = _docked_loop("maze")  # battery at 20 %: the fast-forward carries the charge
    for _ in range(3):
        charging.tick()
    assert charging.sim.is_docked() and not charging.waiting() and charging.pace() == math.inf
    world = load_world("maze")
    sim = Simulation.from_world(world, battery_level=1.0)
    full = SimLoop(sim, NavigationCore(world.map, robot=sim), rate=math.inf)
    for _ in range(3):
        full.tick()
    assert full.sim.is_docked() and full.waiting() and full.pace() == WAITING_RATE


def test_held_and_finite_rates_keep_their_pace() -> None:
    assert _waiting_loop(rate=5.0).pace() == 5.0
    assert _waiting_loop(rate=500.0).pace() == 500.0  # a rate asked for is kept, above the waiting rate too
    world = load_world("maze")
    sim = Simulation.from_world(world)
    held = SimLoop(sim, NavigationCore(world.map, robot=sim), rate=math.inf, hold=True)
    for _ in range(3):
        held.tick()
    assert held.pace() == 1.0
    held.release()
    assert held.pace() == WAITING_RATE  # on its dock, full


def test_a_fleet_waits_only_while_every_robot_does() -> None:
    world = load_world("warehouse")
    fleet = Fleet(world, robots_on_docks(world.all_docks, 2, world.name), seed=3, battery_level=1.0)
    sims = list(fleet)
    navs = [NavigationCore(world.map, robot=sim) for sim in sims]
    loop = SimLoop(sims[0], navs[0], rate=math.inf, world=fleet, navs=navs)
    for _ in range(3):
        loop.tick()
    assert loop.waiting()
    sims[1].set_velocity_command(0.1, 0.0)
    assert not loop.waiting()


def test_a_waiting_simulator_runs_no_faster_than_the_waiting_rate() -> None:
    """Running: the sim time a waiting robot's loop covers is bounded by the wall time it ran (unbounded, this loop
    ran thousands of times real time)."""
    loop = _waiting_loop()
    before = loop.sim.time
    started = time.monotonic()
    loop.start()
    try:
        time.sleep(0.5)
    finally:
        loop.stop()
    elapsed = time.monotonic() - started
    covered = loop.sim.time - before
    assert 0.0 < covered <= WAITING_RATE * elapsed + loop.control_period, (covered, elapsed)


def test_the_command_line_help_gives_the_waiting_rate() -> None:
    from tb4.cli.cmd_sim import RATE_MAX_HELP

    assert f"{WAITING_RATE:g}x while every robot waits" in RATE_MAX_HELP
