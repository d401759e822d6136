"""Nav2's docking_server actions (dock_robot, undock_robot) over the simulated Create 3 dock.

The work is tb4.nav.docking's DockingServerCore (the dock database: one dock, id 'home', type 'create3_dock'; the
DockRobot / UndockRobot tasks, stepped by the loop beside the nav core); this module only checks and converts
goals, and starts them as journaled inputs.
"""

from __future__ import annotations

from typing import Any

from nav2_msgs import action as nav2_action

from tb4.nav.docking import DOCK_ID
from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import pose_to_tuple

__all__ = ["DockingServer", "DOCK_ID"]


class DockingServer:
    """dock_robot / undock_robot on the docking_server node of `nav2` (a tb4.ros.nav2.Nav2Interfaces): goals are
    checked here and run by the robot's tb4.nav.docking.DockingServerCore, which the loop steps."""

    def __init__(self, nav2: Any) -> None:
        self.nav2 = nav2
        self.database = nav2.loop.docking.database
        A = nav2_action
        nav2.serve_action(
            "docking_server", A.DockRobot, "dock_robot", self._dock, invalid_code=A.DockRobot.Result.UNKNOWN
        )
        nav2.serve_action(
            "docking_server", A.UndockRobot, "undock_robot", self._undock, invalid_code=A.UndockRobot.Result.UNKNOWN
        )

    def _dock(self, goal: Any) -> Any:
        staging_time = float(goal.max_staging_time)
        if goal.use_dock_id:
            try:
                dock = self.database.find(goal.dock_id)
            except Exception as exc:
                return _failed(exc)
            pose: tuple[float, float, float] = dock.pose
        else:
            try:
                self.database.check_type(goal.dock_type)
            except Exception as exc:
                return _failed(exc)
            frame = goal.dock_pose.header.frame_id
            if frame not in ("", "map"):
                return _failed(ValueError(f"dock pose must be in frame 'map', got '{frame}'"), 999)
            pose = pose_to_tuple(goal.dock_pose)
        docking = self.nav2.loop.inputs.docking
        return docking.start_dock_robot(pose, bool(goal.navigate_to_staging_pose), staging_time)

    def _undock(self, goal: Any) -> Any:
        docking = self.nav2.loop.inputs.docking
        return docking.start_undock_robot(str(goal.dock_type), float(goal.max_undocking_time))


def _failed(exc: Exception, code: int | None = None) -> ImmediateTask:
    """A goal refused before any work: done at once with its code."""
    error = code if code is not None else int(getattr(exc, "code", 999))
    return ImmediateTask(False, {"success": False, "error_code": error, "error_msg": str(exc)})
