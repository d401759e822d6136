"""Nav2 docking_server tasks. Upstream methods here: dockRobotByPose, dockRobotByID, undockRobot. Each returns a
RunningTask when accepted, None when rejected. (TurtleBot4Navigator's dock()/undock() use the Create 3 actions.)"""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import DockRobot, UndockRobot

from tb4.navigator._base import NavigatorBase
from tb4.navigator._validate import check_name, check_pose_stamped
from tb4.navigator.results import RunningTask

__all__ = ["DockingMixin"]


class DockingMixin(NavigatorBase):
    def dockRobotByPose(
        self, dock_pose: PoseStamped, dock_type: str = "", nav_to_dock: bool = True
    ) -> RunningTask | None:
        """Dock at the dock found at `dock_pose` (use_dock_id false); `nav_to_dock` drives to its staging pose
        first."""
        check_pose_stamped(dock_pose, "dock_pose")
        check_name(dock_type, "dock_type")
        goal = DockRobot.Goal(
            use_dock_id=False, dock_pose=dock_pose, dock_type=dock_type, navigate_to_staging_pose=bool(nav_to_dock)
        )
        p = dock_pose.pose.position
        self.info(f"Docking at pose: ({p.x}, {p.y}) in '{dock_pose.header.frame_id}'...")
        return self._startTask("dock_robot", goal, "DockRobot request was rejected!", RunningTask.DOCK_ROBOT)

    def dockRobotByID(self, dock_id: str, nav_to_dock: bool = True) -> RunningTask | None:
        """Dock at a dock of the docking server's database, by its id."""
        check_name(dock_id, "dock_id")
        if not dock_id:
            raise ValueError("dock_id is empty: give the id of a dock in the docking server's database")
        goal = DockRobot.Goal(use_dock_id=True, dock_id=dock_id, navigate_to_staging_pose=bool(nav_to_dock))
        self.info(f"Docking at dock ID: {dock_id}...")
        return self._startTask("dock_robot", goal, "DockRobot request was rejected!", RunningTask.DOCK_ROBOT)

    def undockRobot(self, dock_type: str = "") -> RunningTask | None:
        """Undock from the current dock (`dock_type` only matters when the server does not know it)."""
        check_name(dock_type, "dock_type")
        self.info(f"Undocking from dock of type: {dock_type}...")
        goal = UndockRobot.Goal(dock_type=dock_type)
        return self._startTask("undock_robot", goal, "UndockRobot request was rejected!", RunningTask.UNDOCK_ROBOT)
