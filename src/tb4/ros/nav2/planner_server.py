"""planner_server and smoother_server: compute_path_to_pose, compute_path_through_poses, is_path_valid, the `plan`
topic, and smooth_path. Every failure is typed (the core's PlanError, or a PlanRequestError for a bad pose) and
becomes the action's own Nav2 error code; nothing is classified by the text of a message."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from nav2_msgs import action as nav2_action
from nav2_msgs.srv import IsPathValid
from nav_msgs.msg import Path as PathMsg

from tb4.nav.planner import PlanError, to_path_code, to_through_poses_code
from tb4.nav.server import NotLocalizedError
from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import duration_to_seconds, path_msg, path_to_array
from tb4.ros.nav2.goals import PlanRequestError, plan_goal, plan_goals, plan_start
from tb4.ros.replies import create_service
from tb4.wire import get_optional, get_poses

if TYPE_CHECKING:
    from tb4.ros.nav2.interfaces import Nav2Interfaces

__all__ = ["PlannerServer", "SmootherServer", "PLANNER_IDS", "SMOOTHER_IDS"]

PLANNER_IDS = ("", "GridBased")
SMOOTHER_IDS = ("", "simple_smoother", "SmoothPath")


class PlannerServer:
    """The planner_server node's actions, service and `plan` topic."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        self.nav2 = nav2
        self.loop = nav2.loop
        self.nav = nav2.nav
        node = nav2.nodes["planner_server"]
        self.plan_pub = node.create_publisher(PathMsg, "plan", 1)
        A = nav2_action
        nav2.serve_action(
            "planner_server", A.ComputePathToPose, "compute_path_to_pose", lambda g: self.compute(g, False)
        )
        nav2.serve_action(
            "planner_server", A.ComputePathThroughPoses, "compute_path_through_poses", lambda g: self.compute(g, True)
        )
        create_service(node, IsPathValid, "is_path_valid", self._is_path_valid, callback_group=nav2.callback_group)
        self._last_plan: Any = None
        self.loop.every(0.1, self._publish_task_plan)
        self.loop.on_reset(self._forget_plan)

    def _forget_plan(self) -> None:
        self._last_plan = None

    def compute(self, goal: Any, through: bool) -> ImmediateTask:
        """One ComputePathToPose (or ThroughPoses) goal, answered at once in the loop."""
        code_of = to_through_poses_code if through else to_path_code
        if goal.planner_id not in PLANNER_IDS:
            message = f"unknown planner_id '{goal.planner_id}' (known: GridBased)"
            return ImmediateTask.failure(code_of(PlanError.INVALID_PLANNER), message)
        try:
            start = plan_start(goal)
            if through:
                result = self.nav.compute_path_through(start, plan_goals(get_poses(goal, "goals")))
            else:
                result = self.nav.compute_path(start, plan_goal(goal.goal))
        except NotLocalizedError as exc:
            return ImmediateTask.failure(code_of(PlanError.TF_ERROR), str(exc))
        except PlanRequestError as exc:
            return ImmediateTask.failure(code_of(exc.error), str(exc))
        fields: dict[str, Any] = {"planning_time": result.planning_time, "error_msg": result.message}
        if result.ok:
            fields["path"] = result.path
            self.plan_pub.publish(path_msg(result.path, self.loop.sim.time))
        fields["error_code"] = code_of(result.error)
        return ImmediateTask(result.ok, fields)

    def publish_plan(self, path: Any, now: float) -> None:
        """A plan on `plan` (RViz and the viewer show it), only when someone listens: a Path message costs ~10 ms."""
        if self.plan_pub.get_subscription_count() > 0:
            self.plan_pub.publish(path_msg(path, now))

    def _publish_task_plan(self, now: float) -> None:
        """Each new global plan of the running navigation task, on `plan` and into the run record."""
        task = self.nav.task
        path = getattr(task, "path", None) if task is not None else None
        if path is None or len(path) == 0 or path is self._last_plan:
            return
        self._last_plan = path  # a new plan is a new array: identity tells us when to publish
        self.publish_plan(path, now)
        if self.nav2.record is not None:
            self.nav2.record.plan(now, path)

    def _is_path_valid(self, request: Any, response: Any) -> Any:
        path = path_to_array(request.path)
        valid, indices = self.loop.call(
            lambda: self.nav.is_path_valid(
                path,
                int(get_optional(request, "max_cost", 254)),  # Jazzy's request has neither: Nav2's defaults
                bool(get_optional(request, "consider_unknown_as_obstacle", False)),
            )
        )
        response.is_valid = bool(valid)
        response.invalid_pose_indices = [int(i) for i in indices]
        return response


class SmootherServer:
    """The smoother_server node's smooth_path action."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        self.nav = nav2.nav
        nav2.serve_action("smoother_server", nav2_action.SmoothPath, "smooth_path", self.smooth)

    def smooth(self, goal: Any) -> ImmediateTask:
        codes = nav2_action.SmoothPath.Result
        if goal.smoother_id not in SMOOTHER_IDS:
            return ImmediateTask.failure(codes.INVALID_SMOOTHER, f"unknown smoother_id '{goal.smoother_id}'")
        path = path_to_array(goal.path)
        if len(path) < 2:
            return ImmediateTask.failure(codes.INVALID_PATH, "a path needs at least 2 poses")
        max_duration = duration_to_seconds(goal.max_smoothing_duration) or 2.0
        result = self.nav.smooth(path, max_duration, bool(goal.check_for_collisions))
        fields = {
            "path": result.path,
            "smoothing_duration": getattr(result, "duration", 0.0),
            "was_completed": bool(result.was_completed),
        }
        if goal.check_for_collisions and result.in_collision:
            message = "smoothed path is in collision"
            return ImmediateTask.failure(codes.SMOOTHED_PATH_IN_COLLISION, message, **fields)
        return ImmediateTask(True, fields)
