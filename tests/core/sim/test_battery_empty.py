"""An empty battery is not silent: at 0 % off the dock the Create 3 stops its motors, says so once, and every goal
that drives fails at once naming the battery, until the dock charges the pack again (no DDS here)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.nav.server import NavigationCore
from tb4.nav.tasks import FAILED, SUCCEEDED, Task
from tb4.sim import motion
from tb4.sim.create3 import BATTERY_EMPTY, RED
from tb4.sim.simulation import Simulation
from tb4.sim.ui import WHITE

pytestmark = pytest.mark.core

DOCK = (0.5, 2.0, math.pi)  # on the west wall, facing it
START = (2.0, 2.0, 0.0)
FAR = (11.0, 2.0, 0.0)  # 9 m east: half a minute of driving
PHYSICS_DT = 0.05  # one physics step per control period, as the nav-core tests step


def corridor() -> OccupancyMap:
    """A walled 12 x 4 m corridor, origin (0, 0)."""
    data = np.zeros((80, 240), dtype=np.int8)
    data[:2, :] = data[-2:, :] = 100
    data[:, :2] = data[:, -2:] = 100
    return OccupancyMap(data, 0.05, 0.0, 0.0)


class Robot:
    """The real Simulation and a NavigationCore stepped together, as the simulator loop steps them."""

    def __init__(self, level: float, start: tuple[float, float, float] = START) -> None:
        grid = corridor()
        self.sim = Simulation(grid, DOCK, start, battery_level=level, physics_dt=PHYSICS_DT)
        self.nav = NavigationCore(grid, robot=self.sim)
        self.nav.set_initial_pose(*start)

    def run(self, until: Callable[[], bool], seconds: float) -> None:
        end = self.sim.time + seconds
        while not until() and self.sim.time < end:
            self.sim.step(1)
            self.nav.step(self.sim.time)


def test_the_battery_runs_flat_during_a_goal_which_fails_at_once_naming_it() -> None:
    # 0.1 % of 26 Wh: about ten seconds of driving (10 W)
    robot = Robot(0.001)
    sim, nav = robot.sim, robot.nav
    goal = nav.start_navigate_to_pose(FAR)
    robot.run(lambda: goal.done, 120.0)
    assert goal.status == FAILED
    assert goal.result() == {"error_code": 9000, "error_msg": BATTERY_EMPTY}
    assert "battery is empty (0 %)" in goal.error_msg and "dock" in goal.error_msg
    empty_at = sim.base.battery_empty_at
    assert empty_at is not None and 5.0 < empty_at < 20.0  # it ran out while driving ...
    assert goal.end_time is not None and goal.end_time - empty_at <= PHYSICS_DT + 1e-9  # ... and the goal ended then
    assert sim.x < 9.0  # far from the goal
    assert sim.battery().percentage == 0.0 and sim.base.battery_empty
    assert [text for _, text in sim.base.events] == ["battery empty: motors stopped"]  # said once

    robot.run(lambda: False, 2.0)
    assert sim.velocity() == (0.0, 0.0)
    x = sim.x
    robot.run(lambda: False, 5.0)
    assert sim.x == x  # it stays put
    assert sim.base.refuse_motion() == BATTERY_EMPTY and sim.drive_disabled() == BATTERY_EMPTY
    assert len(sim.base.events) == 1


def test_every_goal_that_drives_fails_at_once_while_the_battery_is_empty() -> None:
    robot = Robot(0.0)  # off the dock with a flat pack: the motors are off from the start
    sim, nav = robot.sim, robot.nav
    assert sim.base.battery_empty and sim.base.battery_empty_at == 0.0
    started: list[Task] = [
        nav.start_navigate_to_pose(FAR),
        nav.start_navigate_through_poses([(4.0, 2.0, 0.0), FAR]),
        nav.start_follow_waypoints([(4.0, 2.0, 0.0), FAR]),
        nav.start_follow_path(np.array([[2.0, 2.0, 0.0], [4.0, 2.0, 0.0]])),
        nav.start_spin(1.0),
        nav.start_backup(0.2, 0.05, 10.0),
        nav.start_drive_on_heading(0.2, 0.05, 10.0),
        nav.start_assisted_teleop(5.0),
    ]
    for task in started:  # failed before a single step
        assert (task.status, task.error_code, task.error_msg) == (FAILED, task.UNKNOWN, BATTERY_EMPTY), task.name
    # a robot that cannot drive can still wait
    wait = nav.start_wait(0.5)
    robot.run(lambda: wait.done, 5.0)
    assert wait.status == SUCCEEDED

    # the Create 3's own goals and cmd_vel are refused with the same reason
    with pytest.raises(ValueError, match="battery is empty"):
        sim.start_motion(lambda: motion.RotateAngle(lambda: (0.0, 0.0, 0.0), sim.params.drive, 1.0, 1.0))
    assert sim.set_velocity_command(0.2, 0.0) == (False, f"ignored: {BATTERY_EMPTY}")
    dock = sim.start_dock()
    assert dock.status == FAILED and dock.reason == f"rejected: {BATTERY_EMPTY}"


def test_powered_off_by_robot_power_navigation_fails_at_once_too() -> None:
    robot = Robot(1.0)
    robot.sim.base.powered = False  # what robot_power does; the dock wakes it
    goal = robot.nav.start_navigate_to_pose(FAR)
    assert goal.status == FAILED and "powered off (robot_power)" in goal.error_msg


def test_a_drive_goal_running_when_the_battery_runs_flat_ends_with_the_reason() -> None:
    robot = Robot(0.001)
    sim = robot.sim

    def odom() -> tuple[float, float, float]:
        o = sim.odometry()
        return (o.x, o.y, o.yaw)

    drive = sim.start_motion(lambda: motion.DriveDistance(odom, sim.params.drive, 8.0, 0.3))
    robot.run(lambda: drive.done, 60.0)
    assert drive.status == FAILED and drive.reason == BATTERY_EMPTY


def test_through_poses_and_waypoints_mark_the_pose_they_were_driving_to() -> None:
    robot = Robot(0.001)
    through = robot.nav.start_navigate_through_poses([(9.0, 2.0, 0.0), FAR])
    robot.run(lambda: through.done, 120.0)
    status = through.result()["waypoint_statuses"][0]
    assert (status["waypoint_status"], status["error_msg"]) == (3, BATTERY_EMPTY)  # FAILED
    assert through.result()["error_code"] == 9100

    robot = Robot(0.001)
    waypoints = robot.nav.start_follow_waypoints([(9.0, 2.0, 0.0), FAR])
    robot.run(lambda: waypoints.done, 120.0)
    result = waypoints.result()
    assert (result["error_code"], result["error_msg"]) == (600, BATTERY_EMPTY)
    assert [(m["waypoint_index"], m["error_msg"]) for m in result["missed_waypoints"]] == [(0, BATTERY_EMPTY)]


def test_on_the_dock_a_flat_battery_charges_and_the_robot_drives_again() -> None:
    robot = Robot(0.0, start=DOCK)  # docked with a flat pack: the dock powers it and charges it
    sim = robot.sim
    assert sim.is_docked() and not sim.base.battery_empty
    robot.run(lambda: False, 60.0)
    assert sim.battery().power_supply_status == 1 and sim.battery().percentage > 0.0  # charging
    assert sim.start_undock().status == "running"
    robot.run(lambda: not sim.is_docked() and sim.velocity() == (0.0, 0.0), 30.0)
    assert not sim.is_docked() and not sim.base.battery_empty

    # run flat off the dock, then put back on it (by hand): it charges and the motors come back
    robot = Robot(0.0)
    sim = robot.sim
    assert sim.base.battery_empty
    sim.set_pose(*DOCK)
    robot.run(lambda: not sim.base.battery_empty, 1.0)
    assert not sim.base.battery_empty and sim.drive_disabled() == ""
    assert [text for _, text in sim.base.events] == [
        "battery empty: motors stopped",
        "battery charging: motors enabled",
    ]
    assert sim.set_velocity_command(0.0, 0.5)[0]


def test_the_light_ring_pulses_red_below_ten_percent() -> None:
    def ring(level: float) -> set[tuple[int, int, int]]:
        sim = Simulation(corridor(), DOCK, START, battery_level=level, physics_dt=0.01)
        seen = set()
        for _ in range(200):  # two seconds
            sim.step(1)
            seen.add(sim.base.lightring.shown(sim.time)[0])
        return seen

    assert ring(0.5) == {WHITE}
    assert ring(0.09) == {RED, (0, 0, 0)}  # red, then dark: a pulse


def test_running_flat_while_still_is_the_same_step_for_step_as_in_spans() -> None:
    """Steps of a still robot are taken together (Simulation.step), yet the pack runs flat at the same step, with
    the same reading everywhere, as when stepped one at a time."""
    # 6 W idle: 0.03 % of 26 Wh lasts about 4.7 s
    level = 3e-4

    def reading(chunk: int) -> tuple[object, ...]:
        sim = Simulation(corridor(), DOCK, START, battery_level=level, physics_dt=0.01)
        for _ in range(1000 // chunk):
            if chunk > 1:
                sim.step(chunk)
            else:
                sim._step_once()
        base = sim.base
        return (sim.steps, sim._battery.energy_wh, base.battery_empty, base.battery_empty_at, list(base.events))

    reference = reading(1)
    empty_at = reference[3]
    assert isinstance(empty_at, float) and 4.0 < empty_at < 6.0
    for chunk in (5, 100, 1000):
        assert reading(chunk) == reference, chunk
