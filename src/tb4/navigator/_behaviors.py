"""Behaviour tasks. Upstream methods here: spin, backup, driveOnHeading, assistedTeleop. Each returns a
RunningTask when accepted, None when rejected. `time_allowance` takes any positive number of seconds (upstream:
whole seconds only)."""

from __future__ import annotations

from typing import Any

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point
from nav2_msgs.action import AssistedTeleop, BackUp, DriveOnHeading, Spin

from tb4.core.units import to_sec_nanosec
from tb4.navigator._base import NavigatorBase
from tb4.navigator._validate import check_number
from tb4.navigator.results import RunningTask
from tb4.wire import set_supported

__all__ = ["BehaviorMixin", "seconds_msg"]


def seconds_msg(value: Any, what: str) -> Duration:
    """A builtin_interfaces/Duration of `value` positive, finite seconds."""
    seconds = check_number(value, what, positive=True)
    if seconds >= 2**31:
        raise ValueError(f"{what} is too large for a ROS Duration: {value!r}")
    sec, nanosec = to_sec_nanosec(seconds)
    return Duration(sec=sec, nanosec=nanosec)


def _flag(value: Any, what: str) -> bool:
    if not isinstance(value, (bool, int)):
        raise TypeError(f"{what} must be True or False, got {type(value).__name__}")
    return bool(value)


class BehaviorMixin(NavigatorBase):
    def _collision_checks(self, goal: Any, disable_collision_checks: bool) -> None:
        """Kilted's behaviors can skip collision checks; Jazzy's nav2_msgs has no such field, so they stay on."""
        disable = _flag(disable_collision_checks, "disable_collision_checks")
        if set_supported(goal, disable_collision_checks=disable) and disable:
            self.warn("disable_collision_checks needs Kilted's nav2_msgs: on this Jazzy build collision checks stay on")

    def spin(
        self, spin_dist: float = 1.57, time_allowance: float = 10, disable_collision_checks: bool = False
    ) -> RunningTask | None:
        """Rotate in place by `spin_dist` radians (counter-clockwise positive)."""
        goal = Spin.Goal(
            target_yaw=check_number(spin_dist, "spin_dist"),
            time_allowance=seconds_msg(time_allowance, "time_allowance"),
        )
        self._collision_checks(goal, disable_collision_checks)
        self.info(f"Spinning to angle {goal.target_yaw}....")
        return self._startTask("spin", goal, "Spin request was rejected!", RunningTask.SPIN)

    def backup(
        self,
        backup_dist: float = 0.15,
        backup_speed: float = 0.025,
        time_allowance: float = 10,
        disable_collision_checks: bool = False,
    ) -> RunningTask | None:
        """Drive straight backwards `backup_dist` metres at `backup_speed` m/s."""
        goal = BackUp.Goal(
            target=Point(x=check_number(backup_dist, "backup_dist")),
            speed=check_number(backup_speed, "backup_speed", positive=True),
            time_allowance=seconds_msg(time_allowance, "time_allowance"),
        )
        self._collision_checks(goal, disable_collision_checks)
        self.info(f"Backing up {goal.target.x} m at {goal.speed} m/s....")
        return self._startTask("backup", goal, "Backup request was rejected!", RunningTask.BACKUP)

    def driveOnHeading(
        self,
        dist: float = 0.15,
        speed: float = 0.025,
        time_allowance: float = 10,
        disable_collision_checks: bool = False,
    ) -> RunningTask | None:
        """Drive straight ahead `dist` metres at `speed` m/s."""
        goal = DriveOnHeading.Goal(
            target=Point(x=check_number(dist, "dist")),
            speed=check_number(speed, "speed", positive=True),
            time_allowance=seconds_msg(time_allowance, "time_allowance"),
        )
        self._collision_checks(goal, disable_collision_checks)
        self.info(f"Drive {goal.target.x} m on heading at {goal.speed} m/s....")
        return self._startTask(
            "drive_on_heading", goal, "Drive On Heading request was rejected!", RunningTask.DRIVE_ON_HEADING
        )

    def assistedTeleop(self, time_allowance: float = 30) -> RunningTask | None:
        """Let teleop commands (cmd_vel_teleop) through collision checking for `time_allowance` seconds."""
        goal = AssistedTeleop.Goal(time_allowance=seconds_msg(time_allowance, "time_allowance"))
        self.info("Running 'assisted_teleop'....")
        return self._startTask(
            "assisted_teleop", goal, "Assisted Teleop request was rejected!", RunningTask.ASSISTED_TELEOP
        )
