"""Nav2 route server calls. Upstream methods here: getRoute (one-shot ComputeRoute: returns [dense path, sparse
route]) and getAndTrackRoute (ComputeAndTrackRoute, a RunningTask tracked beside the main task; its feedback is
kept complete and in order and getFeedback(task=COMPUTE_AND_TRACK_ROUTE) pops it one message at a time).

`start` and `goal` are both node ids (int, uint16) or both PoseStamped. A mixed pair is a failed request, as
upstream reports it: None and the task error (UNKNOWN, 'Request type fields were invalid!'). Differences from
upstream: getRoute passes `use_start` on (upstream always sent False)."""

from __future__ import annotations

from typing import Any

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputeAndTrackRoute, ComputeRoute
from nav2_msgs.msg import Route
from nav_msgs.msg import Path

from tb4.navigator._base import NavigatorBase
from tb4.navigator._task_client import rejected_code
from tb4.navigator._validate import check_pose_stamped
from tb4.navigator.results import RunningTask, status_name
from tb4.wire import get_optional, set_supported

__all__ = ["RouteMixin", "INVALID_REQUEST"]

INVALID_REQUEST = "Request type fields were invalid!"
_UINT16_MAX = 0xFFFF


def _is_id(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _fill(goal: Any, start: Any, target: Any, use_start: bool) -> bool:
    """Fill a ComputeRoute/ComputeAndTrackRoute goal; False if start and goal are not both ids or both poses."""
    goal.use_start = bool(use_start)
    if _is_id(start) and _is_id(target):
        for value, what in ((start, "start"), (target, "goal")):
            if not 0 <= value <= _UINT16_MAX:
                raise ValueError(f"{what} node id must be within 0..{_UINT16_MAX} (uint16), got {value}")
        goal.start_id, goal.goal_id, goal.use_poses = start, target, False
        return True
    if isinstance(start, PoseStamped) and isinstance(target, PoseStamped):
        check_pose_stamped(target, "goal")
        if use_start:
            check_pose_stamped(start, "start")
        goal.start, goal.goal, goal.use_poses = start, target, True
        return True
    return False


class RouteMixin(NavigatorBase):
    def _getRouteImpl(self, start: int | PoseStamped, goal: int | PoseStamped, use_start: bool = False) -> Any:
        """The whole ComputeRoute result (planning_time, path, route, error_code, error_msg)."""
        request = ComputeRoute.Goal()
        if not _fill(request, start, goal, use_start):
            self.error("Invalid start and goal types. Must be PoseStamped for pose or int for ID")
            self.last_call_status = None
            result = ComputeRoute.Result(error_code=rejected_code(ComputeRoute))
            set_supported(result, error_msg=INVALID_REQUEST)  # Kilted only: the task error keeps it in either format
            self.setTaskError(result.error_code, INVALID_REQUEST)
            return result
        self.info("Getting route...")
        return self._one_shot("compute_route", request, ComputeRoute, "Get route")

    def getRoute(
        self, start: int | PoseStamped, goal: int | PoseStamped, use_start: bool = False
    ) -> list[Path | Route] | None:
        """[dense nav_msgs/Path, sparse nav2_msgs/Route] from `start` to `goal`; None (task error set) on failure."""
        self.clearTaskError()
        result = self._getRouteImpl(start, goal, use_start)
        if self.last_call_status == GoalStatus.STATUS_SUCCEEDED:
            return [result.path, result.route]
        # Jazzy's ComputeRoute result carries only the code: a message is then only the navigator's own (rejection)
        message = str(get_optional(result, "error_msg", self.getTaskError()[1]))
        self.setTaskError(int(result.error_code), message)
        self.warn(
            f"Getting route failed with status {status_name(self.last_call_status)}: "
            f"error {result.error_code}: {message}"
        )
        return None

    def getAndTrackRoute(
        self, start: int | PoseStamped, goal: int | PoseStamped, use_start: bool = False
    ) -> RunningTask | None:
        """Compute a route and track the robot along it (ComputeAndTrackRoute). Runs beside the main task: feed
        each rerouted feedback.path to followPath, as Nav2's example does."""
        self.clearTaskError()
        request = ComputeAndTrackRoute.Goal()
        if not _fill(request, start, goal, use_start):
            self.setTaskError(rejected_code(ComputeAndTrackRoute), INVALID_REQUEST)
            self.error("Invalid start and goal types. Must be PoseStamped for pose or int for ID")
            return None
        self.info("Computing and tracking route...")
        return self._startTask(
            "compute_and_track_route",
            request,
            "Compute and track route was rejected!",
            RunningTask.COMPUTE_AND_TRACK_ROUTE,
            self._tasks.route,
        )
