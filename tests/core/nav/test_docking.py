"""Docking server semantics in the core: staging (skipped within tolerance, navigated otherwise, bounded by
max_staging_time), dock detection, the Create 3 hand-off and Nav2's error codes, cancellation."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest

from tb4.nav.docking import CREATE3_DOCK_TYPE, DockDatabase, DockInstance, DockRobotTask, UndockRobotTask
from tb4.nav.params import load_nav2_params
from tb4.nav.tasks import CANCELED, FAILED, RUNNING, SUCCEEDED

pytestmark = pytest.mark.core

PARAMS = load_nav2_params().section("docking_server", "ros__parameters")


class Create3State:
    def __init__(self) -> None:
        self.status, self.reason, self.canceled = RUNNING, "", False

    @property
    def done(self) -> bool:
        return self.status != RUNNING

    def cancel(self) -> None:
        self.canceled, self.status = True, CANCELED


@dataclass
class FakeRobot:
    dock_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)
    time: float = 0.0
    docked: bool = False
    visible: bool = True
    actions: list = field(default_factory=list)

    def is_docked(self) -> bool:
        return self.docked

    def dock_visible(self) -> bool:
        return self.visible

    def start_dock(self) -> Create3State:
        self.actions.append(Create3State())
        return self.actions[-1]

    def start_undock(self) -> Create3State:
        return self.start_dock()


class FakeNavTask:
    def __init__(self, goal: tuple[float, float, float]) -> None:
        self.goal, self.status, self.error_msg = goal, RUNNING, ""

    @property
    def done(self) -> bool:
        return self.status != RUNNING

    def cancel(self) -> None:
        self.status = CANCELED


@dataclass
class FakeNav:
    where: tuple[float, float, float] | None = (-3.0, 2.0, 0.0)
    tasks: list = field(default_factory=list)

    def pose(self) -> tuple[float, float, float] | None:
        return self.where

    def start_navigate_to_pose(self, goal: tuple[float, float, float]) -> FakeNavTask:
        self.tasks.append(FakeNavTask(tuple(goal)))
        return self.tasks[-1]


def db() -> DockDatabase:
    return DockDatabase([DockInstance("home", CREATE3_DOCK_TYPE, (0.0, 0.0, 0.0))], PARAMS)


def test_database_ids_types_and_staging_pose() -> None:
    d = db()
    assert d.find("home").pose == (0.0, 0.0, 0.0)
    with pytest.raises(Exception) as info:
        d.find("garage")
    assert getattr(info.value, "code", None) == 901 and "known: home" in str(info.value)
    assert d.check_type("") == d.check_type(CREATE3_DOCK_TYPE) == CREATE3_DOCK_TYPE
    with pytest.raises(Exception) as info:
        d.check_type("simple_charging_dock")
    assert getattr(info.value, "code", None) == 902
    x, y, yaw = d.staging_pose((1.0, 2.0, math.pi / 2))
    assert (x, y, yaw) == pytest.approx((1.0, 2.0 - 0.7, math.pi / 2))


def test_full_docking_sequence_with_feedback_states() -> None:
    robot, nav = FakeRobot(), FakeNav()
    task = DockRobotTask(robot, nav, db(), (0.0, 0.0, 0.0))
    task.step(0.0)
    assert task.feedback()["state"] == 1 and nav.tasks[0].goal == pytest.approx((-0.7, 0.0, 0.0))
    nav.tasks[0].status = SUCCEEDED
    robot.time = 5.0
    task.step(5.0)
    assert task.feedback()["state"] == 3 and len(robot.actions) == 1  # detected, Create 3 docking
    assert task.feedback()["docking_time"] == pytest.approx(5.0)
    robot.actions[0].status, robot.docked = SUCCEEDED, True
    task.step(6.0)
    assert task.status == SUCCEEDED and task.result() == {"success": True, "error_code": 0, "error_msg": ""}


def test_every_phase_entered_is_reported_once_even_between_samples() -> None:
    """A feedback sample every few steps would miss a phase passed within them; the task keeps each one."""
    robot, nav = FakeRobot(), FakeNav()
    task = DockRobotTask(robot, nav, db(), (0.0, 0.0, 0.0))
    task.step(0.0)
    nav.tasks[0].status = SUCCEEDED
    task.step(1.0)  # staged, detected, the Create 3 docking: three phases in one step
    robot.actions[0].status, robot.docked = SUCCEEDED, True
    task.step(2.0)  # docked, charging: done
    assert [f["state"] for f in task.drain_phase_feedback()] == [1, 2, 3, 4]
    assert task.drain_phase_feedback() == []


def test_staging_skipped_within_tolerance_or_when_not_asked() -> None:
    robot = FakeRobot()
    task = DockRobotTask(robot, FakeNav(where=(-0.6, 0.1, 0.1)), db(), (0.0, 0.0, 0.0))
    task.step(0.0)
    assert task.feedback()["state"] == 3 and robot.actions
    far_but_told = DockRobotTask(FakeRobot(), FakeNav(), db(), (0.0, 0.0, 0.0), navigate_to_staging_pose=False)
    far_but_told.step(0.0)
    assert far_but_told.feedback()["state"] == 3
    facing_away = FakeNav(where=(-0.7, 0.0, math.pi))  # right spot, wrong heading: l2Norm counts the angle
    DockRobotTask(FakeRobot(), facing_away, db(), (0.0, 0.0, 0.0)).step(0.0)
    assert facing_away.tasks


@pytest.mark.parametrize(
    ("setup", "code", "needle"),
    [
        ("nav_fails", 903, "staging pose"),
        ("staging_timeout", 903, "took over"),
        ("not_localized", 999, "initial pose"),
        ("wrong_pose", 904, "no dock at the requested pose"),
        ("not_visible", 904, "not in sight"),
        ("create3_fails", 905, "Create 3 dock failed: dock timed out"),
        ("left_dock", 906, "left the dock"),
    ],
)
def test_failures_carry_nav2_codes(setup: str, code: int, needle: str) -> None:
    robot, nav = FakeRobot(), FakeNav()
    pose = (0.0, 0.0, 0.0)
    if setup == "not_localized":
        nav.where = None
    if setup == "wrong_pose":
        pose = (2.0, 0.0, 0.0)
    if setup == "not_visible":
        robot.visible = False
    task = DockRobotTask(robot, nav, db(), pose, max_staging_time=10.0)
    task.step(0.0)
    if nav.tasks:
        if setup == "nav_fails":
            nav.tasks[0].status, nav.tasks[0].error_msg = FAILED, "goal is outside the map"
        elif setup == "staging_timeout":
            task.step(11.0)
            assert nav.tasks[0].status == CANCELED  # the staging navigation is stopped
        else:
            nav.tasks[0].status = SUCCEEDED
    task.step(1.0)
    if robot.actions:
        if setup == "create3_fails":
            robot.actions[0].status, robot.actions[0].reason = FAILED, "dock timed out after 30 s"
        else:
            robot.actions[0].status = SUCCEEDED
        task.step(2.0)
    assert task.status == FAILED and task.error_code == code and needle in task.error_msg, task.error_msg
    assert task.result()["success"] is False


def test_already_docked_succeeds_at_once_and_bad_inputs_fail_at_once() -> None:
    task = DockRobotTask(FakeRobot(docked=True), FakeNav(), db(), (0.0, 0.0, 0.0))
    task.step(0.0)
    assert task.status == SUCCEEDED
    for pose, staging in [((math.nan, 0.0, 0.0), 5.0), ((0.0, 0.0, 0.0), math.inf), ((0.0, 0.0, 0.0), -1.0)]:
        bad = DockRobotTask(FakeRobot(), FakeNav(), db(), pose, max_staging_time=staging)
        assert bad.done and bad.error_code == 999


def test_cancel_stops_children() -> None:
    robot, nav = FakeRobot(), FakeNav()
    task = DockRobotTask(robot, nav, db(), (0.0, 0.0, 0.0))
    task.step(0.0)
    task.cancel()
    assert task.status == CANCELED and nav.tasks[0].status == CANCELED
    undock = UndockRobotTask(FakeRobot(docked=True), db(), "", 30.0)
    undock.step(0.0)
    undock.cancel()
    assert undock.status == CANCELED and undock._create3.canceled


def test_undock_codes() -> None:
    assert UndockRobotTask(FakeRobot(docked=True), db(), "other", 30.0).error_code == 902
    assert UndockRobotTask(FakeRobot(docked=False), db(), "", 30.0).error_code == 902
    assert UndockRobotTask(FakeRobot(docked=True), db(), "", 0.0).error_code == 999
    slow = UndockRobotTask(FakeRobot(docked=True), db(), "", 5.0)
    slow.step(0.0)
    slow.step(6.0)
    assert slow.error_code == 905 and "timed out" in slow.error_msg and slow._create3.canceled
    ok = UndockRobotTask(FakeRobot(docked=True), db(), CREATE3_DOCK_TYPE, 30.0)
    ok.step(0.0)
    ok._create3.status = SUCCEEDED
    ok.step(1.0)
    assert ok.status == SUCCEEDED and ok.result()["success"]
