"""Navigation tasks. Upstream methods here: goThroughPoses, goToPose, followWaypoints, followGpsWaypoints,
followPath. Each returns a RunningTask when the server accepted the goal and None when it rejected it (the task
error then holds the action's UNKNOWN code and the reason)."""

from __future__ import annotations

import math
from typing import Any

from geographic_msgs.msg import GeoPose
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import FollowGPSWaypoints, FollowPath, FollowWaypoints, NavigateThroughPoses, NavigateToPose
from nav_msgs.msg import Goals, Path
from std_msgs.msg import Header

from tb4.navigator._base import NavigatorBase
from tb4.navigator._validate import check_name, check_path, check_pose_stamped, check_poses
from tb4.navigator.results import RunningTask
from tb4.wire import set_poses

__all__ = ["NavigationMixin", "check_geo_poses"]


def _check_loops(number_of_loops: Any, goal_index: Any, count: int) -> None:
    for value, what in ((number_of_loops, "number_of_loops"), (goal_index, "goal_index")):
        if isinstance(value, bool) or not isinstance(value, int) or value < 0 or value > 0xFFFFFFFF:
            raise ValueError(f"{what} must be a non-negative int (uint32), got {value!r}")
    if goal_index >= count:
        raise ValueError(f"goal_index {goal_index} is out of range for {count} waypoints")


def check_geo_poses(gps_poses: Any, what: str = "gps_poses") -> list[GeoPose]:
    """A non-empty list of geographic_msgs/GeoPose with a valid WGS 84 position and a usable orientation."""
    if isinstance(gps_poses, (str, bytes, GeoPose)) or not isinstance(gps_poses, (list, tuple)):
        raise TypeError(f"{what} must be a list of geographic_msgs/GeoPose, got {type(gps_poses).__name__}")
    if not gps_poses:
        raise ValueError(f"{what} is empty: give at least one GeoPose")
    for i, pose in enumerate(gps_poses):
        name = f"{what}[{i}]"
        if not isinstance(pose, GeoPose):
            raise TypeError(f"{name} must be a geographic_msgs/GeoPose, got {type(pose).__name__}")
        lat, lon, alt = pose.position.latitude, pose.position.longitude, pose.position.altitude
        if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
            raise ValueError(f"{name}: latitude must be within [-90, 90] degrees, got {lat!r}")
        if not (math.isfinite(lon) and -180.0 <= lon <= 180.0):
            raise ValueError(f"{name}: longitude must be within [-180, 180] degrees, got {lon!r}")
        if math.isinf(alt):  # NaN is geographic_msgs' "no altitude"
            raise ValueError(f"{name}: altitude must be finite or NaN (unknown), got {alt!r}")
        q = pose.orientation
        values = (q.x, q.y, q.z, q.w)
        if not all(math.isfinite(v) for v in values) or sum(v * v for v in values) < 1e-9:
            raise ValueError(f"{name}: orientation must be a finite, non-zero quaternion, got {values!r}")
    return list(gps_poses)


class NavigationMixin(NavigatorBase):
    def goThroughPoses(self, poses: Goals | list[PoseStamped], behavior_tree: str = "") -> RunningTask | None:
        """Navigate through every pose in order (NavigateThroughPoses). Takes a nav_msgs/Goals (Kilted) or a list
        of PoseStamped (Jazzy, Humble); Kilted's own code calls len() on the Goals, we do what it meant."""
        checked = check_poses(poses, "poses")
        check_name(behavior_tree, "behavior_tree")
        if isinstance(poses, Goals):
            header = poses.header
        else:
            header = Header(frame_id=checked[0].header.frame_id, stamp=self.get_clock().now().to_msg())
        self.info(f"Navigating with {len(checked)} goals....")
        goal = NavigateThroughPoses.Goal(behavior_tree=behavior_tree)
        set_poses(goal, "poses", checked, header)  # nav_msgs/Goals on Kilted's wire, a PoseStamped list on Jazzy's
        rejected = f"NavigateThroughPoses request with {len(checked)} was rejected!"
        return self._startTask("navigate_through_poses", goal, rejected, RunningTask.NAVIGATE_THROUGH_POSES)

    def goToPose(self, pose: PoseStamped, behavior_tree: str = "") -> RunningTask | None:
        """Navigate to `pose` (NavigateToPose); follow it with isTaskComplete(task=...)."""
        check_pose_stamped(pose, "pose")
        check_name(behavior_tree, "behavior_tree")
        p = pose.pose.position
        self.info(f"Navigating to goal: {p.x} {p.y}...")
        goal = NavigateToPose.Goal(pose=pose, behavior_tree=behavior_tree)
        rejected = f"NavigateToPose goal to {p.x} {p.y} was rejected!"
        return self._startTask("navigate_to_pose", goal, rejected, RunningTask.NAVIGATE_TO_POSE)

    def followWaypoints(
        self, poses: list[PoseStamped], number_of_loops: int = 0, goal_index: int = 0
    ) -> RunningTask | None:
        """Visit each waypoint in turn (FollowWaypoints); feedback.current_waypoint tells which. Extra options
        (the goal's own fields): repeat `number_of_loops` times, start at `goal_index`."""
        checked = check_poses(poses, "poses")
        _check_loops(number_of_loops, goal_index, len(checked))
        self.info(f"Following {len(checked)} goals....")
        goal = FollowWaypoints.Goal(poses=checked, number_of_loops=number_of_loops, goal_index=goal_index)
        rejected = f"Following {len(checked)} waypoints request was rejected!"
        return self._startTask("follow_waypoints", goal, rejected, RunningTask.FOLLOW_WAYPOINTS)

    def followGpsWaypoints(
        self, gps_poses: list[GeoPose], number_of_loops: int = 0, goal_index: int = 0
    ) -> RunningTask | None:
        """Visit each GPS waypoint (latitude/longitude, FollowGPSWaypoints) in turn; same options as
        followWaypoints."""
        checked = check_geo_poses(gps_poses)
        _check_loops(number_of_loops, goal_index, len(checked))
        self.info(f"Following {len(checked)} gps goals....")
        goal = FollowGPSWaypoints.Goal(gps_poses=checked, number_of_loops=number_of_loops, goal_index=goal_index)
        rejected = f"Following {len(checked)} gps waypoints request was rejected!"
        return self._startTask("follow_gps_waypoints", goal, rejected, RunningTask.FOLLOW_GPS_WAYPOINTS)

    def followPath(self, path: Path, controller_id: str = "", goal_checker_id: str = "") -> RunningTask | None:
        """Follow a given path with the controller (FollowPath)."""
        check_path(path)
        check_name(controller_id, "controller_id")
        check_name(goal_checker_id, "goal_checker_id")
        self.info("Executing path...")
        goal = FollowPath.Goal(path=path, controller_id=controller_id, goal_checker_id=goal_checker_id)
        return self._startTask("follow_path", goal, "FollowPath goal was rejected!", RunningTask.FOLLOW_PATH)
