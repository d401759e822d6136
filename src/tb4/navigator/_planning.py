"""Planning and smoothing: one-shot actions that return a path (or None, with the task error set) without disturbing
the running task. Upstream methods here: getPath, getPathThroughPoses, smoothPath (and _getPathImpl,
_getPathThroughPosesImpl, _smoothPathImpl, which return the whole result)."""

from __future__ import annotations

from typing import Any

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputePathThroughPoses, ComputePathToPose, SmoothPath
from nav_msgs.msg import Goals, Path
from std_msgs.msg import Header

from tb4.navigator._base import NavigatorBase
from tb4.navigator._behaviors import seconds_msg
from tb4.navigator._validate import check_name, check_number, check_path, check_pose_stamped, check_poses
from tb4.navigator.results import status_name
from tb4.wire import set_poses

__all__ = ["PlanningMixin"]


class PlanningMixin(NavigatorBase):
    def _finish(self, result: Any, what: str) -> Path | None:
        if self.last_call_status == GoalStatus.STATUS_SUCCEEDED:
            return result.path
        self.setLastError(result.error_code, result.error_msg)
        self.warn(
            f"{what} failed with status {status_name(self.last_call_status)}: "
            f"error {result.error_code}: {result.error_msg}"
        )
        return None

    def _getPathImpl(
        self, start: PoseStamped | None, goal: PoseStamped, planner_id: str = "", use_start: bool = False
    ) -> Any:
        """The full ComputePathToPose result (path, planning_time, error_code, error_msg)."""
        check_pose_stamped(goal, "goal")
        if use_start:
            check_pose_stamped(start, "start")
        check_name(planner_id, "planner_id")
        request = ComputePathToPose.Goal(
            goal=goal,
            start=start if start is not None else PoseStamped(),
            planner_id=planner_id,
            use_start=bool(use_start),
        )
        self.info("Getting path...")
        return self._one_shot("compute_path_to_pose", request, ComputePathToPose, "Get path")

    def getPath(
        self, start: PoseStamped | None, goal: PoseStamped, planner_id: str = "", use_start: bool = False
    ) -> Path | None:
        """A path from `start` (or the robot's pose unless use_start) to `goal`; None if planning failed."""
        return self._finish(self._getPathImpl(start, goal, planner_id, use_start), "Getting path")

    def _getPathThroughPosesImpl(
        self, start: PoseStamped | None, goals: Any, planner_id: str = "", use_start: bool = False
    ) -> Any:
        poses = check_poses(goals, "goals")
        if use_start:
            check_pose_stamped(start, "start")
        check_name(planner_id, "planner_id")
        request = ComputePathThroughPoses.Goal(
            start=start if start is not None else PoseStamped(),
            planner_id=planner_id,
            use_start=bool(use_start),
        )
        set_poses(request, "goals", poses, Header(frame_id=poses[0].header.frame_id))
        self.info("Getting path...")
        return self._one_shot("compute_path_through_poses", request, ComputePathThroughPoses, "Get path through poses")

    def getPathThroughPoses(
        self, start: PoseStamped | None, goals: Goals | list[PoseStamped], planner_id: str = "", use_start: bool = False
    ) -> Path | None:
        """A path through every pose of `goals` (list of PoseStamped or nav_msgs/Goals); None on failure."""
        return self._finish(
            self._getPathThroughPosesImpl(start, goals, planner_id, use_start), "Getting path through poses"
        )

    def _smoothPathImpl(
        self, path: Path, smoother_id: str = "", max_duration: float = 2.0, check_for_collision: bool = False
    ) -> Any:
        check_path(path)
        check_name(smoother_id, "smoother_id")
        seconds = check_number(max_duration, "max_duration", positive=True)
        request = SmoothPath.Goal(
            path=path,
            smoother_id=smoother_id,
            max_smoothing_duration=seconds_msg(seconds, "max_duration"),
            check_for_collisions=bool(check_for_collision),
        )
        self.info("Smoothing path...")
        return self._one_shot("smooth_path", request, SmoothPath, "Smooth path")

    def smoothPath(
        self, path: Path, smoother_id: str = "", max_duration: float = 2.0, check_for_collision: bool = False
    ) -> Path | None:
        """The smoothed path; None if smoothing failed (e.g. the result would collide)."""
        return self._finish(
            self._smoothPathImpl(path, smoother_id, max_duration, check_for_collision), "Smoothing path"
        )
