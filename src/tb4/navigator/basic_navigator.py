"""BasicNavigator: Nav2 Simple Commander's API (Kilted, and the Jazzy/Humble call styles) with bounded waits and
event-driven completion.

    rclpy.init()
    nav = BasicNavigator()
    nav.setInitialPose(pose); nav.waitUntilNav2Active()
    task = nav.goToPose(goal)                      # a RunningTask, or None if rejected
    while not nav.isTaskComplete(task=task):       # isTaskComplete() works too
        feedback = nav.getFeedback(task=task)
    print(nav.getResult(), nav.getTaskError())

The navigator is an rclpy Node spun by its own daemon thread, started only once the whole object (subclasses
included) is built; it may also be added to the user's executor. Upstream's method groups live in mixins:
  _navigation   goThroughPoses, goToPose, followWaypoints, followGpsWaypoints, followPath
  _behaviors    spin, backup, driveOnHeading, assistedTeleop
  _docking      dockRobotByPose, dockRobotByID, undockRobot
  _task_state   cancelTask, isTaskComplete, getFeedback, getResult
  _base         clearTaskError, setTaskError, getTaskError, info, warn, error, debug
  _localization setInitialPose, waitUntilNav2Active, lifecycleStartup, lifecycleShutdown
  _planning     getPath, getPathThroughPoses, smoothPath
  _routes       getRoute, getAndTrackRoute
  _costmaps     changeMap, clearAllCostmaps, clearLocalCostmap, clearGlobalCostmap, clearCostmapExceptRegion,
                clearCostmapAroundRobot, getGlobalCostmap, getLocalCostmap
This module: __init__, destroyNode, destroy_node, upstream's attributes; action goals and the running tasks are
in _task_client.TaskClient.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

from nav2_msgs.action import (
    AssistedTeleop,
    BackUp,
    ComputeAndTrackRoute,
    ComputePathThroughPoses,
    ComputePathToPose,
    ComputeRoute,
    DockRobot,
    DriveOnHeading,
    FollowGPSWaypoints,
    FollowPath,
    FollowWaypoints,
    NavigateThroughPoses,
    NavigateToPose,
    SmoothPath,
    Spin,
    UndockRobot,
)
from rclpy.action import ActionClient
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.parameter import Parameter
from rclpy.waitable import Waitable

from tb4.navigator._behaviors import BehaviorMixin
from tb4.navigator._costmaps import CostmapMixin
from tb4.navigator._docking import DockingMixin
from tb4.navigator._localization import LocalizationMixin
from tb4.navigator._navigation import NavigationMixin
from tb4.navigator._planning import PlanningMixin
from tb4.navigator._routes import RouteMixin
from tb4.navigator._services import ServiceCaller
from tb4.navigator._spinner import BackgroundSpinner, wait_until
from tb4.navigator._task_client import TaskClient
from tb4.navigator._task_state import TaskStateMixin
from tb4.navigator._validate import check_name, check_number
from tb4.navigator.results import RunningTask, TaskResult
from tb4.navigator.timeouts import DEFAULT_TIMEOUTS, NavigatorTimeout, NavigatorTimeouts

__all__ = ["BasicNavigator", "TaskResult", "RunningTask", "NAV2_ACTIONS"]

#: Relative action names and types, as Nav2 serves them.
NAV2_ACTIONS: dict[str, Any] = {
    "navigate_to_pose": NavigateToPose,
    "navigate_through_poses": NavigateThroughPoses,
    "follow_waypoints": FollowWaypoints,
    "follow_path": FollowPath,
    "compute_path_to_pose": ComputePathToPose,
    "compute_path_through_poses": ComputePathThroughPoses,
    "smooth_path": SmoothPath,
    "compute_route": ComputeRoute,
    "compute_and_track_route": ComputeAndTrackRoute,
    "follow_gps_waypoints": FollowGPSWaypoints,
    "spin": Spin,
    "backup": BackUp,
    "drive_on_heading": DriveOnHeading,
    "assisted_teleop": AssistedTeleop,
    "dock_robot": DockRobot,
    "undock_robot": UndockRobot,
}


class _SpinsWhenBuilt(type):
    """Starts the navigator's executor thread after the outermost __init__ returned, so no thread ever sees a
    half-built navigator (rclpy registers an action client with its node before it finishes building it)."""

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        navigator = super().__call__(*args, **kwargs)
        navigator._spinner.start()
        return navigator


class BasicNavigator(
    NavigationMixin,
    BehaviorMixin,
    DockingMixin,
    TaskStateMixin,
    LocalizationMixin,
    PlanningMixin,
    RouteMixin,
    CostmapMixin,
    metaclass=_SpinsWhenBuilt,
):
    """Upstream-compatible navigator. Extra keyword-only options: `timeouts`, `use_sim_time` (None = automatic).

    Subclasses may create clients and subscriptions in their __init__ freely: spinning starts after it returns
    (or at the first request sent from inside it)."""

    def __init__(
        self,
        node_name: str = "basic_navigator",
        namespace: str = "",
        *,
        timeouts: NavigatorTimeouts | None = None,
        use_sim_time: bool | None = None,
    ) -> None:
        check_name(node_name, "node_name")
        check_name(namespace, "namespace")
        if timeouts is not None and not isinstance(timeouts, NavigatorTimeouts):
            raise TypeError(f"timeouts must be a NavigatorTimeouts, got {type(timeouts).__name__}")
        if use_sim_time is not None and not isinstance(use_sim_time, bool):
            raise TypeError(f"use_sim_time must be True, False or None, got {use_sim_time!r}")
        # Every callback of ours is thread-safe, so one reentrant group: a MutuallyExclusive default group can be
        # left "busy" forever by a user's executor that is shut down between taking and running a callback, which
        # would then block this node in every other executor.
        self._navigator_group = ReentrantCallbackGroup()
        super().__init__(node_name=node_name, namespace=namespace)
        self.timeouts = timeouts or DEFAULT_TIMEOUTS
        self._destroyed = False
        self._spinner = BackgroundSpinner(self)  # started by _SpinsWhenBuilt once construction is complete
        self._clock_undecided = False  # automatic sim-time detection still looking for /clock (see _configure_clock)
        self._tasks = TaskClient(self, lambda: self.timeouts, self._before_request, self._spinner.paused)
        self._calls = ServiceCaller(self, lambda: self.timeouts, self._before_request, self._spinner.paused)
        for name, action_type in NAV2_ACTIONS.items():
            self._tasks.add(action_type, name)
        self._setup_localization()
        self._setup_costmap_clients()
        self._configure_clock(use_sim_time)

    def _ensure_spun(self) -> None:
        spinner = getattr(self, "_spinner", None)
        if spinner is not None:
            spinner.ensure_spun()

    def _before_request(self) -> None:
        """Before the first goal or service call the clock is settled for good, then the node is spun."""
        self._adopt_late_clock()
        self._clock_undecided = False
        self._ensure_spun()

    def _configure_clock(self, use_sim_time: bool | None) -> None:
        """Follow the simulator's /clock when one publishes it (waits then scale with accelerated time).

        Automatic detection looks for `timeouts.clock_discovery` seconds, and if it finds nothing keeps looking
        until the first goal, service call or sleep(): on a loaded machine discovering the simulator can take
        longer than the look, and a navigator settled on wall time would time an accelerated simulation wrongly."""
        if use_sim_time is None:
            limit = self.timeouts.clock_discovery
            use_sim_time = limit > 0 and wait_until(self._clock_published, limit)
            self._clock_undecided = limit > 0 and not use_sim_time
        if use_sim_time:
            self._follow_sim_clock()

    def _clock_published(self) -> bool:
        return self.count_publishers("/clock") > 0

    def _follow_sim_clock(self) -> None:
        self._clock_undecided = False
        self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
        self.debug("Using the simulator's /clock")

    def _adopt_late_clock(self) -> None:
        """Follow a /clock publisher discovered after the constructor's look, while the clock is undecided."""
        if self._clock_undecided and self._clock_published():
            self._follow_sim_clock()

    @property
    def default_callback_group(self) -> CallbackGroup:
        return self._navigator_group

    @property
    def waitables(self) -> Iterator[Waitable[Any]]:
        """The node's waitables, less action clients rclpy has registered but not finished building (their _lock
        comes last): an executor, ours or the user's, never touches a half-built client, whoever creates it."""
        for waitable in super().waitables:
            if isinstance(waitable, ActionClient) and "_lock" not in vars(waitable):
                continue
            yield waitable

    @property
    def uses_sim_time(self) -> bool:
        self._adopt_late_clock()
        return bool(self.get_parameter("use_sim_time").value)

    def sleep(self, seconds: float) -> None:
        """Wait `seconds` on the node's clock: simulated seconds under the simulator, so a charging wait of 15 s
        passes as fast as the simulation runs. NavigatorTimeout if that clock stops (no /clock for
        `timeouts.response` wall seconds)."""
        duration = check_number(seconds, "seconds", non_negative=True)
        self._before_request()
        clock = self.get_clock()
        end = clock.now().nanoseconds + int(duration * 1e9)
        last_tick, last_value = time.monotonic(), clock.now().nanoseconds
        while (now := clock.now().nanoseconds) < end:
            if now != last_value:
                last_tick, last_value = time.monotonic(), now
            elif time.monotonic() - last_tick > self.timeouts.response:
                raise NavigatorTimeout(
                    f"the clock stopped for {self.timeouts.response:g} s during sleep({seconds}) — "
                    "did the simulator stop publishing /clock?"
                )
            time.sleep(min(0.01, (end - now) / 1e9))

    # --- upstream's attributes --------------------------------------------------------------------------------
    @property
    def goal_handle(self) -> Any:
        return self._tasks.goal_handle

    @property
    def result_future(self) -> Any:
        return self._tasks.result_future

    @property
    def feedback(self) -> Any:
        return self._tasks.feedback

    @property
    def status(self) -> int | None:
        return self._tasks.status

    @property
    def route_goal_handle(self) -> Any:
        return self._tasks.route.goal_handle

    @property
    def route_result_future(self) -> Any:
        return self._tasks.route.result_future

    @property
    def route_feedback(self) -> list[Any]:
        """Route feedback not yet read by getFeedback(task=COMPUTE_AND_TRACK_ROUTE), oldest first (a copy)."""
        return list(self._tasks.route.feedback_queue)

    # --- lifetime ------------------------------------------------------------------------------------------------
    def destroyNode(self) -> None:
        self.destroy_node()

    def destroy_node(self) -> None:
        if getattr(self, "_destroyed", True) is False:
            self._destroyed = True
            self._spinner.stop()
            self._tasks.destroy()
            self._calls.destroy()
        super().destroy_node()
