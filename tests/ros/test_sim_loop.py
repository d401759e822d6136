"""The simulator loop survives failing publishers and tells watchers when tasks end (no DDS involved)."""

from __future__ import annotations

import math
import threading

from tb4.nav.server import NavigationCore
from tb4.ros.loop import IDLE_TICK_LIMIT, SimLoop
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
