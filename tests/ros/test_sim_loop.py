"""The simulator loop survives failing publishers and tells watchers when tasks end (no DDS involved)."""

from __future__ import annotations

import threading

from tb4.nav.server import NavigationCore
from tb4.ros.loop import SimLoop
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
