"""Steps of a still robot are taken together (Simulation._still_steps): the same state to the last bit as stepping
one at a time, whatever comes in between (commands, teleports, buttons, moving obstacles, a flat battery)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.sim.obstacles import Obstacle
from tb4.sim.simulation import Simulation
from tb4.sim.ui import ORANGE, LedAnimation
from tb4.sim.world import WORLDS_DIR, load_world

pytestmark = pytest.mark.core

MOVER = Obstacle(shape="circle", radius=0.25, path=((-3.0, 2.5), (3.0, 2.5)), speed=0.5)


def room() -> OccupancyMap:
    """An empty 10 x 8 m room, origin (-5, -4), walls 0.1 m thick."""
    data = np.zeros((160, 200), dtype=np.int8)
    data[:2, :] = data[-2:, :] = 100
    data[:, :2] = data[:, -2:] = 100
    return OccupancyMap(data, 0.05, -5.0, -4.0)


Script = dict[int, Callable[[Simulation], object]]  # step number -> what to do to the simulation then


def state(sim: Simulation) -> str:
    """Everything a step can change, as text: repr keeps every bit of a float (and the sign of a zero)."""
    b, base, p = sim._battery, sim.base, sim.base.proprio
    return repr(
        (
            sim.steps, sim.x, sim.y, sim.yaw, sim.velocity(), sim.odometry(), sim.in_contact,
            b.energy_wh, b.power, b.charging, sim.battery(),
            p.gyro_yaw, p.ticks, p.mouse_x, p.imu(), p.left_rad_s, p.slipping,
            base.lightring.system, base.cliff_frames, base.dropped, base.hazards(), base.powered, base.stall,
            [(h.time, h.kind, h.x, h.y) for h in sim.pop_hazards()],
        )
    )  # fmt: skip


def run(make: Callable[[], Simulation], script: Script, total: int, chunk: int) -> tuple[list[str], Simulation]:
    """Run `script` for `total` steps: one `_step_once` at a time (chunk 0, the reference) or `step(chunk)` at a
    time. The state is read at every script entry and every 500 steps."""
    sim = make()
    seen = []
    done = 0
    marks = sorted({*script, *range(0, total + 1, 500), total})
    for mark in marks:
        while done < mark:
            n = min(chunk, mark - done) if chunk else 1
            if chunk:
                sim.step(n)
            else:
                sim._step_once()
            done += n
        seen.append(state(sim))
        if mark in script:
            script[mark](sim)
    return seen, sim


def same_as_one_step_at_a_time(
    make: Callable[[], Simulation], script: Script, total: int
) -> tuple[Simulation, list[str]]:
    """The simulation stepped in chunks (the last chunk size's), and the reference states it matched."""
    reference, _ = run(make, script, total, 0)
    for chunk in (1, 5, 997):
        seen, sim = run(make, script, total, chunk)
        assert seen == reference, f"chunk {chunk}"
    return sim, reference


def count_single_steps(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls = [0]
    single = Simulation._step_once

    def counted(self: Simulation) -> None:
        calls[0] += 1
        single(self)

    monkeypatch.setattr(Simulation, "_step_once", counted)
    return calls


def test_charging_on_the_dock_for_an_hour_is_taken_in_few_steps(monkeypatch: pytest.MonkeyPatch) -> None:
    def make() -> Simulation:
        return Simulation.from_world(load_world("warehouse"), battery_level=0.18, odom_noise=True, seed=3)

    script: Script = {
        40_000: lambda s: s.start_undock(),
        42_000: lambda s: s.set_velocity_command(0.0, 0.5),  # turn in place, then stand again
        42_400: lambda s: s.reset_odometry(1.0, 2.0, 7.0),  # an unwrapped heading, wrapped by the next step
    }
    sim, _ = same_as_one_step_at_a_time(make, script, 50_000)
    assert sim.battery().percentage > 0.2 and not sim.is_docked()
    calls = count_single_steps(monkeypatch)
    sim = make()
    sim.step(360_000)  # an hour on the dock: the warehouse's moving obstacles are far from it
    assert sim.is_docked() and sim.battery().percentage > 0.45
    assert calls[0] < 1_000


def test_a_moving_obstacle_still_bumps_a_still_robot_at_the_same_step() -> None:
    def make() -> Simulation:
        return Simulation(room(), (4.0, 3.0, 0.0), (0.0, 2.5, 0.0), obstacles=[MOVER])

    sim, reference = same_as_one_step_at_a_time(make, {}, 3_000)  # the mover passes x = 0 at t = 6 s, and back
    assert "'bump'" in "".join(reference)  # the run under test did see the bump (compared above, step for step)
    assert sim.steps == 3_000


def test_a_still_robot_off_the_dock_drains_to_empty_the_same_way() -> None:
    def make() -> Simulation:
        return Simulation(room(), (4.0, 3.0, 0.0), (0.0, 0.0, 0.0), battery_level=0.001)

    sim, _ = same_as_one_step_at_a_time(make, {100: lambda s: s.set_velocity_command(0.2, 0.0)}, 40_000)
    assert sim.battery().percentage == 0.0
    assert not sim.set_velocity_command(0.2, 0.0)[0]


def test_person_inputs_and_teleports_during_a_still_spell(tmp_path: Path) -> None:
    world = tmp_path / "lab.yaml"
    world.write_text(
        f"name: lab\nmap: {WORLDS_DIR / 'depot_map.yaml'}\ndock: [0.0, 0.0, 0.0]\nstart: [-6.0, -1.0, 0]\n"
        "cliffs:\n  - {shape: box, position: [-9.0, -1.0], size: [1.0, 3.0]}\n"
    )

    def make() -> Simulation:
        return Simulation.from_world(load_world(world), obstacles=[Obstacle("circle", 0.2, path=((-4.0, 2.0),))])

    green = ((0, 255, 0),) * 6
    script: Script = {
        200: lambda s: s.base.press("button_1", 1.5, s.time),
        900: lambda s: setattr(s.base.lightring, "animation", LedAnimation(1, green, 2.0, s.time)),
        1_500: lambda s: s.set_pose(-8.4, -1.0, math.pi),  # the front cliff sensors over the edge
        2_000: lambda s: s.base.set_safety_override("full"),
        2_500: lambda s: s.kidnap(-6.0, -1.0, 1.0),
        3_000: lambda s: setattr(s.base, "estop", True),
        3_500: lambda s: setattr(s.base, "estop", False),
        3_550: lambda s: s.base.set_safety_override("none"),
        **{k: lambda s: s.set_velocity_command(-0.3, 0.0) for k in range(3_600, 3_900, 30)},  # up to the backup limit
        4_200: lambda s: s.base.set_safety_override("full"),  # the light ring leaves orange at the next step
        4_201: lambda s: None,
    }
    sim, reference = same_as_one_step_at_a_time(make, script, 5_000)
    assert any("cliff_front" in seen for seen in reference[3:])  # the teleport's cliff was seen, in both
    assert str(ORANGE) in reference[-4] and str(ORANGE) not in reference[-2]  # backup limit, then the override
    assert sim.pose().x == pytest.approx(-6.0) and not sim.base.lifted


def test_far_moving_obstacles_are_left_out_of_a_step_without_changing_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """While every moving obstacle is too far to matter, a step does not compute where they are: the same run as
    one that always takes them into account, bit for bit, through drives that meet them head-on."""
    movers = [MOVER, Obstacle(shape="circle", radius=0.3, path=((2.0, -3.0), (2.0, 3.0)), speed=0.4, mode="loop")]

    def make(always: bool) -> Simulation:
        sim = Simulation(room(), (4.0, 3.0, 0.0), (-4.0, 2.5, 0.0), obstacles=movers, odom_noise=True, seed=7)
        if always:
            sim._movers_near = lambda: True  # type: ignore[method-assign]
        return sim

    def drive(sim: Simulation) -> tuple[list[str], list[float]]:
        seen, bumps_x = [], []
        for k in range(8_000):
            if k % 5 == 0:  # along the first mover's line, forward and back, then across the second one's
                ahead = (k // 800) % 2 == 0
                sim.set_velocity_command(0.3 if ahead else -0.2, 0.0 if k < 4_000 else 0.3 * math.sin(k / 200.0))
            sim.step(1)
            bumps_x += [h.x for h in sim._hazards]
            if k % 50 == 0:
                seen.append(state(sim))
        return seen, bumps_x

    reference, bumps_x = drive(make(always=True))
    assert any(-3.5 < x < 3.5 for x in bumps_x)  # a mover hit it (the walls are at x = -4.9 and 4.9)
    positions = [0]
    real = Simulation.moving_circles

    def counted(self: Simulation, t: float | None = None) -> list[tuple[float, float, float]]:
        positions[0] += 1
        return real(self, t)

    monkeypatch.setattr(Simulation, "moving_circles", counted)
    assert drive(make(always=False))[0] == reference
    assert positions[0] < 8_000 // 2  # most steps did without them
