"""A fleet in one world: determinism, robot-robot contact, robots in each other's lidar, shared docks."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tb4.config import ConfigError
from tb4.sim.fleet import Fleet
from tb4.sim.fleet_spec import RobotSpec, robots_on_docks
from tb4.sim.hazards import BUMP
from tb4.sim.world import WORLDS_DIR, load_world

pytestmark = pytest.mark.core


def three_robots(world_name: str = "warehouse") -> tuple:
    world = load_world(world_name)
    return world, robots_on_docks(world.all_docks, 3, world.name)


def drive_fleet(seed: int, robots: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Undock every robot, then drive them on different arcs with noise on; (true poses, odometry, scans)."""
    world = load_world("warehouse")
    fleet = Fleet(
        world, robots_on_docks(world.all_docks, robots, world.name), seed=seed, odom_noise=True, lidar_noise=True
    )
    for sim in fleet:
        sim.start_undock()
    fleet.step(600)
    poses, odom, scans = [], [], []
    for k in range(40):
        for i, sim in enumerate(fleet):
            sim.set_velocity_command(0.3, 0.2 * (i - 1) + 0.05 * math.sin(k))
        fleet.step(10)
        for sim in fleet:
            poses.append((sim.x, sim.y, sim.yaw))
            o = sim.odometry()
            odom.append((o.x, o.y, o.yaw))
        scans.append(np.concatenate([sim.scan().ranges for sim in fleet]))
    return np.array(poses), np.array(odom), np.array(scans)


def test_three_robots_replay_bit_identically() -> None:
    a, b = drive_fleet(7), drive_fleet(7)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x, y, equal_nan=True)
    other = drive_fleet(8)
    assert not np.array_equal(a[1], other[1])  # the seed matters


def test_adding_a_robot_keeps_the_others_noise() -> None:
    """Robot k's noise depends on (seed, k) only: robot 1's odometry drift is the same with 2 or 3 robots."""
    _, odom2, _ = drive_fleet(3, robots=2)
    _, odom3, _ = drive_fleet(3, robots=3)
    assert np.array_equal(odom2.reshape(40, 2, 3)[:, 0], odom3.reshape(40, 3, 3)[:, 0])


def test_first_robot_streams_are_a_single_robots() -> None:
    from tb4.sim.simulation import Simulation

    world = load_world("warehouse")
    single = Simulation.from_world(world, seed=5, odom_noise=True)
    fleet = Fleet(world, robots_on_docks(world.all_docks, 1, world.name), seed=5, odom_noise=True)
    for sim in (single, fleet["/robot1"]):
        sim.start_undock()
        sim.step(600)
    assert fleet["/robot1"].odometry() == single.odometry()


def head_on(gap: float = 1.0) -> Fleet:
    world = load_world("warehouse")
    a = RobotSpec("/robot1", (-5.0, 4.0, 0.0), world.dock)
    b = RobotSpec("/robot2", (-5.0 + gap, 4.0, math.pi), world.all_docks[1])
    return Fleet(world, [a, b], seed=1)


def test_robots_collide_and_both_feel_the_bump() -> None:
    fleet = head_on()
    r1, r2 = fleet["/robot1"], fleet["/robot2"]
    bumps: dict[str, list] = {"/robot1": [], "/robot2": []}
    zones: dict[str, set] = {"/robot1": set(), "/robot2": set()}
    for _ in range(300):
        r1.set_velocity_command(0.3, 0.0)  # robot1 drives into robot2, which stands still
        fleet.step(1)
        for name, sim in fleet.robots.items():
            bumps[name] += sim.pop_hazards()
            zones[name] |= {h.frame for h in sim.base.hazards() if h.type == BUMP}
        gap = math.hypot(r1.x - r2.x, r1.y - r2.y)
        assert gap >= 2 * r1.params.drive.radius - 1e-6  # never overlapping
    assert [h.kind for h in bumps["/robot1"]] == ["bump"]
    assert [h.kind for h in bumps["/robot2"]] == ["bump"]
    assert "bump_front_center" in zones["/robot1"] and "bump_front_center" in zones["/robot2"]
    assert r1.x > -5.0 + 0.5  # it drove until the contact


def test_lidar_sees_the_other_robot() -> None:
    fleet = head_on(gap=1.5)
    r1 = fleet["/robot1"]
    scan = r1.scan()
    front = round(-scan.angle_min / scan.angle_increment)  # the beam along the robot's heading
    ahead = scan.ranges[front]
    radius = fleet["/robot2"].params.drive.radius
    assert ahead == pytest.approx(1.5 - radius, abs=0.05)
    alone = Fleet(load_world("warehouse"), [RobotSpec("/robot1", (-5.0, 4.0, 0.0), (0.0, 0.0, 0.0))])
    assert alone["/robot1"].scan().ranges[front] > ahead + 1.0


def test_busy_dock_refuses_a_dock_goal_and_a_free_one_takes_the_robot() -> None:
    world = load_world("warehouse")
    dock0, dock1, dock2 = world.all_docks[:3]
    fleet = Fleet(world, [RobotSpec("/robot1", (-0.8, 1.0, 0.0), dock0), RobotSpec("/robot2", dock1, dock1)])
    r1 = fleet["/robot1"]
    state = r1.start_dock()  # in front of dock 1, where robot2 sits
    assert state.status == "failed" and "occupied by /robot2" in state.reason
    r1.set_pose(-0.8, -1.0, 0.0)  # in front of the free dock 2
    fleet.step(1)
    state = r1.start_dock()
    assert state.status == "running", state.reason
    for _ in range(300):
        fleet.step(10)
        if state.done:
            break
    assert state.status == "succeeded" and r1.is_docked()
    assert math.hypot(r1.x - dock2[0], r1.y - dock2[1]) < 0.05
    assert r1.battery().power_supply_status == 1  # charging (not full yet) on the dock it docked at


def test_robots_on_docks_needs_enough_docks() -> None:
    world = load_world("maze")
    assert [r.namespace for r in robots_on_docks(world.all_docks, 3, "maze")] == ["/robot1", "/robot2", "/robot3"]
    with pytest.raises(ValueError, match="maze has 3 dock"):
        robots_on_docks(world.all_docks, 4, "maze")


def write_world(tmp_path: Path, body: str) -> Path:
    path = tmp_path / "fleet.yaml"
    path.write_text(f"map: {WORLDS_DIR / 'warehouse_map.yaml'}\n" + body, encoding="utf-8")
    return path


def test_world_lists_robots_and_docks(tmp_path: Path) -> None:
    world = load_world(
        write_world(
            tmp_path,
            "docks: [[0, 0, 0], [0, 1, 0]]\n"
            "robots:\n  - {namespace: alpha}\n  - {namespace: /beta, start: [-3, 4, 90], dock: 1}\n",
        )
    )
    assert world.dock == (0.0, 0.0, 0.0) and len(world.all_docks) == 2
    alpha, beta = world.robots
    assert (alpha.namespace, alpha.start, alpha.dock) == ("/alpha", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    assert beta.namespace == "/beta" and beta.start[:2] == (-3.0, 4.0) and beta.dock == (0.0, 1.0, 0.0)


@pytest.mark.parametrize(
    ("body", "key", "problem"),
    [
        ("dock: [0, 0, 0]\ndocks: [[0, 1, 0]]\n", "dock", "either 'dock'"),
        ("docks: [[0, 0, 0], [0, 0.2, 0]]\n", "docks[1]", "too close to docks[0]"),
        (
            "docks: [[0, 0, 0], [0, 1, 0]]\nrobots: [{namespace: a}, {namespace: a, dock: 1}]\n",
            "robots[1].namespace",
            "used by another robot",
        ),
        (
            "docks: [[0, 0, 0], [0, 1, 0]]\nrobots: [{namespace: a}, {namespace: b, dock: 0}]\n",
            "robots[1].dock",
            "taken by '/a'",
        ),
        ("dock: [0, 0, 0]\nrobots: [{namespace: a, dock: 2}]\n", "robots[0].dock", "must be <= 0"),
        ("dock: [0, 0, 0]\nrobots: [{namespace: 'robot-1'}]\n", "robots[0].namespace", "invalid namespace"),
        ("dock: [0, 0, 0]\nrobots: [{namespace: a, strat: [1, 1]}]\n", "robots[0].strat", "did you mean 'start'"),
        (
            "dock: [0, 0, 0]\nrobots: [{namespace: a}, {namespace: b, start: [0.1, 0, 0]}]\n",
            "robots[1].start",
            "overlaps robot '/a'",
        ),
    ],
)
def test_bad_fleet_keys_name_file_and_key(tmp_path: Path, body: str, key: str, problem: str) -> None:
    path = write_world(tmp_path, body)
    with pytest.raises(ConfigError) as info:
        load_world(path)
    assert info.value.key == key and problem in info.value.problem and str(path) in str(info.value)


def test_a_fleet_world_keeps_its_map() -> None:
    """LoadMap would give one robot another world than the others: refused with the reason."""
    fleet = head_on()
    with pytest.raises(ValueError, match="2 robots of this simulator share one world"):
        fleet["/robot2"].set_grid(fleet["/robot2"].grid)


def test_checking_only_near_robots_matches_checking_all() -> None:
    """Fleet.step checks only robots within sensor reach at each physics step; the run matches one that checks
    every robot at every step (a head-on contact, a robot driving past, one far away)."""

    def run(all_peers: bool) -> tuple[list, list]:
        world = load_world("warehouse")
        specs = [
            RobotSpec("/robot1", (-5.0, 4.0, 0.0), world.dock),
            RobotSpec("/robot2", (-3.5, 4.0, math.pi), world.all_docks[1]),
            RobotSpec("/robot3", (-4.0, 5.0, 0.0), world.all_docks[2]),
            RobotSpec("/robot4", (5.0, 4.0, 0.0), world.all_docks[3]),
        ]
        fleet = Fleet(world, specs, seed=2, odom_noise=True)
        sims = list(fleet)
        poses, events = [], []
        for _ in range(120):
            for sim, (v, w) in zip(sims, [(0.3, 0.0), (0.2, 0.05), (0.3, -0.1), (0.3, 0.2)], strict=True):
                sim.set_velocity_command(v, w)
            if all_peers:
                for _ in range(5):
                    for sim in sims:
                        sim.peers = [(o.x, o.y, o.params.drive.radius) for o in sims if o is not sim]
                        sim.step(1)
            else:
                fleet.step(5)
            poses.append([(s.x, s.y, s.yaw) for s in sims])
            events.append([[h.kind for h in s.pop_hazards()] for s in sims])
        return poses, events

    near_poses, near_events = run(all_peers=False)
    all_poses, all_events = run(all_peers=True)
    assert near_events == all_events and any(any(e) for e in near_events)  # the same bumps, and there were some
    np.testing.assert_allclose(np.array(near_poses), np.array(all_poses), atol=1e-9)
