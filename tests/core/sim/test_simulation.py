"""Simulation: determinism, clock, commands, odometry, scans, hazards, map switch, worlds."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from tb4.core.geometry import arc_pose, wrap_angle
from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import default_robot_params
from tb4.sim.obstacles import Obstacle, PathMover
from tb4.sim.simulation import HazardEvent, LaserScan, Simulation
from tb4.sim.world import load_world

pytestmark = pytest.mark.core

RES = 0.05


def room() -> OccupancyMap:
    """10 x 8 m room (origin -5, -4) with a pillar at (3, 2)."""
    data = np.zeros((160, 200), dtype=np.int8)
    data[:2, :] = data[-2:, :] = 100
    data[:, :2] = data[:, -2:] = 100
    data[115:125, 155:165] = 100
    return OccupancyMap(data, RES, -5.0, -4.0)


MOVER = Obstacle(shape="circle", radius=0.25, path=((-3.0, 2.5), (3.0, 2.5)), speed=0.5)
BOX = Obstacle(shape="box", size=(0.6, 0.4), yaw=0.3, path=((-3.0, -2.5),))


def scripted_run(seed: int, noise: bool = True) -> tuple[np.ndarray, list, list]:
    sim = Simulation(
        room(), (0.0, 0.0, 0.0), (-1.0, -1.0, 0.3), obstacles=[MOVER, BOX], seed=seed,
        odom_noise=noise, lidar_noise=noise,
    )  # fmt: skip
    poses, odoms, scans = [], [], []
    for k in range(300):
        if k % 5 == 0:
            sim.set_velocity_command(0.3 * math.cos(k / 40), 1.2 * math.sin(k / 25))
        sim.step(2)
        p = sim.pose()
        poses.append((p.x, p.y, p.yaw))
        odoms.append(sim.odometry())
        if k % 10 == 0:
            scans.append(sim.scan().ranges.copy())
    return np.array(poses), odoms, scans


def test_same_seed_same_commands_identical_runs_bit_for_bit() -> None:
    pa, oa, sa = scripted_run(5)
    pb, ob, sb = scripted_run(5)
    assert pa.tobytes() == pb.tobytes()
    assert oa == ob
    assert all(a.tobytes() == b.tobytes() for a, b in zip(sa, sb, strict=True))
    pc, oc, sc = scripted_run(6)
    assert pc.tobytes() == pa.tobytes()  # ground truth does not depend on the noise seed
    assert oc != oa
    assert any(a.tobytes() != c.tobytes() for a, c in zip(sa, sc, strict=True))


def test_clock_is_steps_times_dt() -> None:
    sim = Simulation(room(), (0, 0, 0), (0, 0, 0), physics_dt=0.01)
    sim.step(1000)
    assert sim.time == 10.0
    assert sim.steps == 1000
    with pytest.raises(ValueError):
        Simulation(room(), (0, 0, 0), (0, 0, 0), physics_dt=0.0)
    with pytest.raises(ValueError):
        Simulation(room(), (0, 0, 0), (math.nan, 0, 0))


def test_kinematics_follow_closed_form_arcs_after_the_ramp() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (-2.0, -2.0, 0.0))
    v, w = 0.2, 0.6
    for _ in range(40):  # 0.4 s: past both ramps (0.2/0.9 s, 0.6/3.0 s)
        sim.set_velocity_command(v, w)
        sim.step()
    assert sim.velocity() == (pytest.approx(v), pytest.approx(w))
    p0 = sim.pose()
    for _ in range(250):
        sim.set_velocity_command(v, w)
        sim.step()
    expected = arc_pose(p0.x, p0.y, p0.yaw, v, w, 2.5)
    p = sim.pose()
    assert (p.x, p.y) == (pytest.approx(expected[0], abs=1e-9), pytest.approx(expected[1], abs=1e-9))
    assert abs(wrap_angle(p.yaw - expected[2])) < 1e-9


def test_command_timeout_and_clamping() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (-2.0, -2.0, 0.0))
    ok, reason = sim.set_velocity_command(2.0, 0.0)
    assert ok and "clamped" in reason
    sim.step(50)
    assert sim.velocity()[0] == pytest.approx(0.31)
    sim.step(60)  # the command is older than 0.5 s: the robot ramps down and stops
    assert sim.velocity() == (0.0, 0.0)
    x = sim.pose().x
    sim.step(100)
    assert sim.pose().x == x


def test_garbage_commands_never_crash_and_change_nothing() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (-2.0, -2.0, 0.0))
    sim.set_velocity_command(0.2, 0.0)
    for v, w in [(math.nan, 0), (0, math.inf), ("x", 0), (None, None), (1e300, 0), (object(), 1), (1j, 0)]:
        ok, reason = sim.set_velocity_command(v, w)  # type: ignore[arg-type]
        assert not ok and reason
    sim.step(20)
    assert sim.velocity()[0] == pytest.approx(0.18)  # still ramping towards the last good command


def test_odometry_starts_at_zero_in_the_start_frame_and_ignores_teleports() -> None:
    start = (1.0, -1.0, math.pi / 2)
    sim = Simulation(room(), (4.0, 3.0, 0.0), start)
    o = sim.odometry()
    assert (o.x, o.y, o.yaw) == (0.0, 0.0, 0.0)
    for _ in range(150):
        sim.set_velocity_command(0.25, 0.0)
        sim.step()
    o, p = sim.odometry(), sim.pose()
    assert o.x == pytest.approx(p.y - start[1], abs=1e-9)  # forward in odom = +y in the map
    assert o.y == pytest.approx(0.0, abs=1e-9)
    assert o.v == pytest.approx(0.25)
    sim.set_pose(0.0, 0.0, 0.0)
    assert sim.odometry() == o


def test_scan_is_cached_per_step_and_sees_moving_obstacles() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (-3.0, 0.5, math.pi / 2), obstacles=[MOVER])
    s1 = sim.scan()
    assert isinstance(s1, LaserScan)
    assert sim.scan() is s1
    # beam 0 looks along +y at the mover (at path[0] = (-3, 2.5) at t = 0): 2.0 m minus its radius
    assert s1.ranges[0] == pytest.approx(2.0 - 0.25, abs=1e-6)
    sim.step(400)  # 4 s: the mover is now 2 m further east, out of beam 0
    s2 = sim.scan()
    assert s2 is not s1 and s2.time == 4.0
    mx, my = MOVER.position_at(4.0)
    assert (mx, my) == pytest.approx((-1.0, 2.5))
    assert s2.ranges[0] == pytest.approx(4.0 - 2 * RES - 0.5, abs=RES)  # the north wall
    bearing = round(math.degrees(math.atan2(my - 0.5, mx + 3.0) - math.pi / 2)) % 360
    assert s2.ranges[bearing] < math.hypot(mx + 3.0, my - 0.5)


def test_static_obstacles_are_seen_and_block() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (-3.0, -1.0, -math.pi / 2), obstacles=[BOX])
    assert sim.scan().ranges[0] < 1.5 - 0.2 + RES  # the box centre is 1.5 m ahead
    for _ in range(1000):
        sim.set_velocity_command(0.3, 0.0)
        sim.step()
    assert sim.pose().y > -2.5 + 0.2
    assert [h.kind for h in sim.pop_hazards()] == ["bump"]


def test_hazards_are_recorded_once_per_contact_and_popped() -> None:
    sim = Simulation(room(), (0.0, 0.0, 0.0), (3.5, 0.0, 0.0))
    for _ in range(700):
        sim.set_velocity_command(0.3, 0.0)
        sim.step()
    hazards = sim.pop_hazards()
    assert len(hazards) == 1 and isinstance(hazards[0], HazardEvent)
    assert hazards[0].kind == "bump" and hazards[0].x == pytest.approx(5.0 - 2 * RES - 0.175, abs=0.01)
    assert sim.in_contact
    assert sim.pop_hazards() == []
    for _ in range(100):
        sim.set_velocity_command(-0.2, 0.0)
        sim.step()
    for _ in range(300):
        sim.set_velocity_command(0.3, 0.0)
        sim.step()
    assert len(sim.pop_hazards()) == 1  # a second press after backing off


def test_moving_obstacle_hitting_the_robot_is_a_bump() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (0.0, 2.5, 0.0), obstacles=[MOVER])
    sim.step(700)  # the mover passes through x = 0 at t = 6 s
    assert [h.kind for h in sim.pop_hazards()] == ["bump"]


def test_set_grid_switches_the_map_live() -> None:
    sim = Simulation(room(), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), obstacles=[BOX])
    before = sim.scan().ranges[0]
    walled = room()
    walled.data[:, 110:112] = 100  # a wall 0.5 m ahead
    sim.set_grid(walled)
    after = sim.scan().ranges[0]
    assert before == pytest.approx(5.0 - 2 * RES, abs=RES)
    assert after == pytest.approx(0.5, abs=RES)
    assert sim.field.clearance(-3.0, -2.5) < 0.0  # the static box is still there after the switch
    for _ in range(300):
        sim.set_velocity_command(0.3, 0.0)
        sim.step()
    assert sim.pose().x < 0.5


def test_battery_level_and_empty_battery() -> None:
    sim = Simulation(room(), (4.0, 3.0, 0.0), (0.0, 0.0, 0.0), battery_level=0.3)
    b = sim.battery()
    assert b.percentage == pytest.approx(0.3) and b.power_supply_status == 2
    sim._battery.energy_wh = 0.0
    sim.step()
    ok, reason = sim.set_velocity_command(0.2, 0.0)
    assert not ok and "battery" in reason


@dataclass
class FakeWorld:
    """Just the World contract Simulation.from_world relies on."""

    map: OccupancyMap
    dock: tuple[float, float, float]
    start: tuple[float, float, float]
    obstacles: tuple = ()
    name: str = "fake"
    map_path: Path = Path("fake.yaml")
    source: Path = Path("fake_world.yaml")
    destinations: dict = field(default_factory=dict)

    def static_obstacle_mask(self) -> np.ndarray:
        mask = self.map.occupied_mask().copy()
        mask[75:85, 60:70] = True  # something only the world knows about
        return mask


def test_from_world_uses_the_world_contract() -> None:
    world = FakeWorld(room(), (0.0, 0.0, 0.0), (1.0, 0.0, math.pi), obstacles=(MOVER,))
    sim = Simulation.from_world(world, seed=3, physics_dt=0.02)
    p = sim.pose()
    assert (p.x, p.y, abs(p.yaw)) == (1.0, 0.0, pytest.approx(math.pi))
    assert sim.dock_pose == (0.0, 0.0, 0.0) and sim.physics_dt == 0.02
    ranges = sim.scan().ranges
    assert ranges[0] == pytest.approx(1.0 + 5.0 - 70 * RES, abs=RES)  # the world's extra static cells
    assert len(sim.moving_circles()) == 1


def test_shipped_warehouse_world() -> None:
    world = load_world("warehouse")
    sim = Simulation.from_world(world)
    assert sim.is_docked() and sim.dock_visible()
    assert sim.battery().power_supply_status == 4  # full on the dock
    state = sim.start_undock()
    while state.status == "running":
        sim.step(10)
    assert state.status == "succeeded"
    scan = sim.scan()
    assert np.isfinite(scan.ranges).sum() > 100  # many beams reach beyond 12 m in the warehouse
    for ob in world.moving_obstacles:
        mover = PathMover(ob)
        for t in np.linspace(0.0, 400.0, 97):
            assert mover.position(float(t)) == pytest.approx(ob.position_at(float(t)), abs=1e-9)


def test_params_are_shared_defaults() -> None:
    sim = Simulation(room(), (0, 0, 0), (0, 0, 0))
    assert sim.params is default_robot_params()
