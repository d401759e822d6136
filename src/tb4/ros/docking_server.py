"""Nav2's docking_server actions (dock_robot, undock_robot) over the simulated Create 3 dock.

The work is tb4.nav.docking's DockRobotTask / UndockRobotTask, stepped beside the nav core; this module only
converts goals and builds the world's dock database (one dock, id 'home', type 'create3_dock').
"""

from __future__ import annotations

from typing import Any

from nav2_msgs import action as nav2_action

from tb4.nav.docking import CREATE3_DOCK_TYPE, DockDatabase, DockInstance, DockRobotTask, UndockRobotTask
from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import pose_to_tuple
from tb4.ros.side_tasks import SideTasks

__all__ = ["DockingServer", "DOCK_ID"]

DOCK_ID = "home"


class DockingServer:
    """dock_robot / undock_robot on the docking_server node of `nav2` (a tb4.ros.nav2.Nav2Interfaces)."""

    def __init__(self, nav2: Any, side: SideTasks) -> None:
        self.nav2 = nav2
        self.side = side
        sim = nav2.loop.sim
        params = nav2.nav.params.section("docking_server", "ros__parameters")
        self.database = DockDatabase([DockInstance(DOCK_ID, CREATE3_DOCK_TYPE, tuple(sim.dock_pose))], params)
        A = nav2_action
        nav2.serve_action(
            "docking_server", A.DockRobot, "dock_robot", self._dock, invalid_code=A.DockRobot.Result.UNKNOWN
        )
        nav2.serve_action(
            "docking_server", A.UndockRobot, "undock_robot", self._undock, invalid_code=A.UndockRobot.Result.UNKNOWN
        )

    def _preempt(self) -> None:
        for task in self.side.running(DockRobotTask) + self.side.running(UndockRobotTask):
            task.cancel()

    def _dock(self, goal: Any) -> Any:
        sim, nav = self.nav2.loop.sim, self.nav2.nav
        self._preempt()
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
        task = DockRobotTask(sim, nav, self.database, pose, bool(goal.navigate_to_staging_pose), staging_time)
        return self.nav2.loop.call_outside_replay(lambda: self.side.add(task), "a docking_server dock_robot goal")

    def _undock(self, goal: Any) -> Any:
        self._preempt()
        timeout = float(goal.max_undocking_time)
        task = UndockRobotTask(self.nav2.loop.sim, self.database, goal.dock_type, timeout)
        return self.nav2.loop.call_outside_replay(lambda: self.side.add(task), "a docking_server undock_robot goal")


def _failed(exc: Exception, code: int | None = None) -> ImmediateTask:
    """A goal refused before any work: done at once with its code."""
    error = code if code is not None else int(getattr(exc, "code", 999))
    return ImmediateTask(False, {"success": False, "error_code": error, "error_msg": str(exc)})
