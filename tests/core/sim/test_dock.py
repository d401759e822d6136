"""Create 3 dock semantics: visibility, docked test, dock/undock actions, rejection, cancel, time limit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.core.geometry import wrap_angle
from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import default_robot_params
from tb4.sim.battery import POWER_SUPPLY_STATUS_CHARGING, POWER_SUPPLY_STATUS_DISCHARGING
from tb4.sim.dock import dock_relative, dock_visible, is_docked
from tb4.sim.obstacles import Obstacle
from tb4.sim.simulation import Simulation

pytestmark = pytest.mark.core

P = default_robot_params().dock
DOCK = (1.0, 2.0, math.pi / 2)  # docked robot faces +y; the station is just north of it


def open_map() -> OccupancyMap:
    """8 x 8 m free area around the dock (origin -3, -2), with the station body drawn 0.2 m ahead of DOCK."""
    res = 0.03
    data = np.zeros((267, 267), dtype=np.int8)
    grid = OccupancyMap(data, res, -3.0, -2.0)
    r0, c0 = grid.world_to_cell(0.8, 2.2)
    r1, c1 = grid.world_to_cell(1.2, 2.4)
    data[r0 : r1 + 1, c0 : c1 + 1] = 100
    return OccupancyMap(data, res, -3.0, -2.0)


def behind(dist: float, lateral: float = 0.0, heading_off: float = 0.0) -> tuple[float, float, float]:
    """A pose `dist` behind the docked pose (and `lateral` to its left), heading_off from facing the dock."""
    x, y, yaw = DOCK
    return (
        x - dist * math.cos(yaw) - lateral * math.sin(yaw),
        y - dist * math.sin(yaw) + lateral * math.cos(yaw),
        yaw + heading_off,
    )


def run(sim: Simulation, state, limit: float = 40.0) -> None:
    while state.status == "running":
        sim.step(10)
        assert sim.time < limit


def test_dock_relative_frame() -> None:
    px, py, th = dock_relative(behind(0.5, 0.1, 0.2), DOCK)
    assert (px, py, th) == (pytest.approx(-0.5), pytest.approx(0.1), pytest.approx(0.2))


@pytest.mark.parametrize(
    ("pose", "visible"),
    [
        (behind(0.0), True),
        (behind(0.5), True),
        (behind(0.95), True),
        (behind(1.5), True),
        (behind(1.9), False),  # too far
        (behind(1.0, lateral=1.0, heading_off=-math.pi / 2), True),  # like the tutorials: (-1, 1) facing EAST
        (behind(-0.3), False),  # ahead of the docked pose
        (behind(0.5, heading_off=math.radians(75)), True),
        (behind(0.5, heading_off=math.radians(85)), False),  # not facing the dock
        (behind(0.5, heading_off=math.pi), False),
        (behind(0.6, lateral=0.3, heading_off=-math.atan2(0.3, 0.6 + P.station_offset)), True),
    ],
)
def test_dock_visibility(pose: tuple[float, float, float], visible: bool) -> None:
    assert dock_visible(pose, DOCK, P) is visible


def test_is_docked_tolerances() -> None:
    assert is_docked(DOCK, DOCK, P)
    assert is_docked(behind(0.02, heading_off=0.08), DOCK, P)
    assert not is_docked(behind(0.05), DOCK, P)
    assert not is_docked(behind(0.0, heading_off=0.15), DOCK, P)


def test_undock_reverses_then_turns_around() -> None:
    sim = Simulation(open_map(), DOCK, DOCK)
    assert sim.is_docked()
    assert sim.battery().power_supply_status != POWER_SUPPLY_STATUS_DISCHARGING
    state = sim.start_undock()
    assert state.status == "running" and state.is_docked
    run(sim, state)
    assert state.status == "succeeded"
    assert not state.is_docked and not sim.is_docked()
    px, py, th = dock_relative(tuple(vars(sim.pose()).values()), DOCK)
    assert px == pytest.approx(-0.4, abs=0.01) and abs(py) < 0.01
    assert abs(wrap_angle(th - math.pi)) < 0.03
    assert sim.time < P.action_timeout
    assert sim.battery().power_supply_status == POWER_SUPPLY_STATUS_DISCHARGING


def test_undock_rejected_when_not_docked_and_dock_rejected_when_docked() -> None:
    sim = Simulation(open_map(), DOCK, DOCK)
    state = sim.start_dock()
    assert (state.status, state.reason) == ("failed", "rejected: already docked")
    sim.set_pose(*behind(0.5))
    state = sim.start_undock()
    assert state.status == "failed" and "not docked" in state.reason


def test_dock_rejected_when_not_visible() -> None:
    sim = Simulation(open_map(), DOCK, behind(0.5, heading_off=math.pi))
    state = sim.start_dock()
    assert state.status == "failed" and "not visible" in state.reason
    assert not state.sees_dock
    sim.step(100)
    assert sim.pose() == sim.pose()  # nothing moves the robot
    assert sim.velocity() == (0.0, 0.0)


@pytest.mark.parametrize(
    "start",
    [
        behind(0.6),
        behind(0.9, lateral=0.25, heading_off=-0.2),
        behind(0.4, lateral=-0.2, heading_off=0.4),
        behind(0.25, lateral=0.1, heading_off=-0.3),
    ],
)
def test_dock_from_visible_poses_succeeds_and_charges(start: tuple[float, float, float]) -> None:
    sim = Simulation(open_map(), DOCK, start, battery_level=0.5)
    assert sim.dock_visible()
    state = sim.start_dock()
    assert state.status == "running" and state.sees_dock
    run(sim, state)
    assert (state.status, state.reason) == ("succeeded", "docked")
    assert state.is_docked and sim.is_docked()
    assert sim.time < P.action_timeout
    assert sim.pop_hazards() == []  # it did not ram the station
    level = sim.battery().percentage
    sim.step(1000)
    assert sim.battery().power_supply_status == POWER_SUPPLY_STATUS_CHARGING
    assert sim.battery().percentage > level


def test_undock_then_dock_round_trip() -> None:
    sim = Simulation(open_map(), DOCK, DOCK)
    run(sim, sim.start_undock())
    sim.set_velocity_command(0.0, 1.0)  # turn back to face the dock
    while abs(wrap_angle(sim.pose().yaw - DOCK[2])) > 0.05:
        sim.set_velocity_command(0.0, 0.5)
        sim.step()
    state = sim.start_dock()
    run(sim, state)
    assert state.status == "succeeded" and sim.is_docked()


def test_velocity_commands_are_ignored_while_an_action_runs() -> None:
    a = Simulation(open_map(), DOCK, DOCK)
    b = Simulation(open_map(), DOCK, DOCK)
    sa, sb = a.start_undock(), b.start_undock()
    for _ in range(200):
        ok, reason = b.set_velocity_command(0.3, 1.0)
        assert not ok and "undock action running" in reason
        a.step()
        b.step()
    assert a.pose() == b.pose()
    assert sa.status == sb.status == "running"


def test_cancel_stops_the_robot() -> None:
    sim = Simulation(open_map(), DOCK, DOCK)
    state = sim.start_undock()
    sim.step(100)
    assert sim.velocity()[0] < 0.0
    state.cancel()
    assert state.status == "canceled"
    sim.step(50)
    assert sim.velocity() == (0.0, 0.0)
    pose = sim.pose()
    sim.step(100)
    assert sim.pose() == pose
    assert sim.set_velocity_command(0.1, 0.0)[0]  # teleop works again
    state.cancel()  # cancelling a finished action changes nothing
    assert state.status == "canceled"


def test_dock_gives_up_after_30_seconds_when_blocked() -> None:
    blocker = Obstacle(shape="circle", radius=0.1, path=(behind(0.4)[:2],))
    sim = Simulation(open_map(), DOCK, behind(0.9), obstacles=[blocker])
    state = sim.start_dock()
    assert state.status == "running"
    run(sim, state, limit=35.0)
    assert state.status == "failed" and "timed out" in state.reason
    assert sim.time == pytest.approx(P.action_timeout, abs=0.011)
    assert [h.kind for h in sim.pop_hazards()][:1] == ["bump"]
    assert state.sees_dock  # feedback kept updating: it still sees the dock from where it is stuck
    sim.step(100)
    assert sim.velocity() == (0.0, 0.0)


def test_second_action_is_rejected_while_one_runs() -> None:
    sim = Simulation(open_map(), DOCK, DOCK)
    first = sim.start_undock()
    second = sim.start_undock()
    assert first.status == "running"
    assert second.status == "failed" and "already running" in second.reason


def test_dock_succeeds_from_random_visible_poses() -> None:
    rng = np.random.default_rng(11)
    sim = Simulation(open_map(), DOCK, DOCK)
    tried = 0
    while tried < 25:
        pose = behind(rng.uniform(0.1, 1.0), rng.uniform(-0.5, 0.5), rng.uniform(-0.6, 0.6))
        sim.set_pose(*pose)
        if not sim.dock_visible():
            continue
        tried += 1
        start = sim.time
        state = sim.start_dock()
        while state.status == "running":
            sim.step(10)
        assert state.status == "succeeded", (pose, state)
        assert sim.time - start < P.action_timeout
