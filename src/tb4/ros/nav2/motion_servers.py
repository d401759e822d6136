"""controller_server and behavior_server: follow_path, the behaviors (spin, backup, drive_on_heading, wait,
assisted_teleop) and assisted teleop's input topics."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from geometry_msgs.msg import Twist
from nav2_msgs import action as nav2_action
from std_msgs.msg import Empty

from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import duration_to_seconds, path_to_array
from tb4.ros.nav2.goals import finite, straight_line
from tb4.wire import get_optional, result_code

if TYPE_CHECKING:
    from tb4.ros.nav2.interfaces import Nav2Interfaces

__all__ = ["ControllerServer", "BehaviorServer", "CONTROLLER_IDS"]

CONTROLLER_IDS = ("", "FollowPath")


class ControllerServer:
    """The controller_server node's follow_path action (regulated pure pursuit in the core)."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        self.nav = nav2.loop.inputs.nav
        nav2.serve_action("controller_server", nav2_action.FollowPath, "follow_path", self.follow_path)

    def follow_path(self, goal: Any) -> Any:
        codes = nav2_action.FollowPath.Result
        if goal.controller_id not in CONTROLLER_IDS:
            return ImmediateTask.failure(codes.INVALID_CONTROLLER, f"unknown controller_id '{goal.controller_id}'")
        path = path_to_array(goal.path)
        if len(path) == 0:
            return ImmediateTask.failure(codes.INVALID_PATH, "empty path")
        return self.nav.start_follow_path(path)


class BehaviorServer:
    """The behavior_server node's actions, and `cmd_vel_teleop` / `preempt_teleop` for assisted teleop."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        A = nav2_action
        loop = nav2.loop
        nav = loop.inputs.nav  # goals start tasks through the journaled inputs
        self.loop, self.nav = loop, nav
        name = "behavior_server"
        behaviors: tuple[tuple[Any, str, Callable[[Any], Any], int], ...] = (
            # (action type, action name, goal -> core task, code for a malformed goal)
            (
                A.Spin,
                "spin",
                lambda g: nav.start_spin(
                    finite(g.target_yaw, "target_yaw"),
                    duration_to_seconds(g.time_allowance),
                    bool(get_optional(g, "disable_collision_checks", False)),
                ),
                A.Spin.Result.UNKNOWN,
            ),
            (A.BackUp, "backup", lambda g: nav.start_backup(*straight_line(g)), A.BackUp.Result.INVALID_INPUT),
            (
                A.DriveOnHeading,
                "drive_on_heading",
                lambda g: nav.start_drive_on_heading(*straight_line(g)),
                A.DriveOnHeading.Result.INVALID_INPUT,
            ),
            (A.Wait, "wait", lambda g: nav.start_wait(duration_to_seconds(g.time)), result_code(A.Wait, "UNKNOWN")),
            (
                A.AssistedTeleop,
                "assisted_teleop",
                lambda g: nav.start_assisted_teleop(duration_to_seconds(g.time_allowance)),
                A.AssistedTeleop.Result.UNKNOWN,
            ),
        )
        for action_type, action_name, start, invalid_code in behaviors:
            nav2.serve_action(name, action_type, action_name, start, invalid_code=invalid_code)
        node = nav2.nodes[name]
        node.create_subscription(Twist, "cmd_vel_teleop", self._teleop, 10)
        node.create_subscription(Empty, "preempt_teleop", self._preempt, 10)

    def _teleop(self, msg: Twist) -> None:
        v, w = msg.linear.x, msg.angular.z
        if math.isfinite(v) and math.isfinite(w):
            self.nav.teleop_velocity(v, w)

    def _preempt(self, _msg: Empty) -> None:
        self.nav.preempt_teleop()
