"""BasicNavigator: Nav2 Simple Commander's API (Kilted, and the Jazzy/Humble call styles) with bounded waits and
event-driven completion.

    rclpy.init()
    nav = BasicNavigator()
    nav.setInitialPose(pose); nav.waitUntilNav2Active()
    task = nav.goToPose(goal)                      # a RunningTask, or None if rejected
    while not nav.isTaskComplete(task=task):       # isTaskComplete() works too
        feedback = nav.getFeedback(task=task)
    print(nav.getResult(), nav.getTaskError())

Laid out like upstream's robot_navigator.py, so a reader who knows it finds each method where upstream has it:
one class, __init__ and destroy first, then every public method in upstream's order (setInitialPose ...
lifecycleShutdown, info/warn/error/debug), then what we add (Jazzy-era names, sleep, upstream's attributes), then
the private helpers. It stays one class, as upstream's is, so the public API reads in one place; the machinery
lives beside it: _task_client (action goals and the running tasks), _liveness (is a running goal's server still
there?), _signals (SIGINT/SIGTERM cancel the running goals), _services (bounded service calls),
tb4.ros.background (the node's executor thread), _goals and _validate (goal fields and argument checks),
results, timeouts.

The navigator is an rclpy Node spun by its own daemon thread, started only once the whole object (subclasses
included) is built; it may also be added to the user's executor.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Iterator
from typing import Any

from action_msgs.msg import GoalStatus
from geographic_msgs.msg import GeoPose
from geometry_msgs.msg import Point, PoseStamped, PoseWithCovarianceStamped
from lifecycle_msgs.srv import GetState
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
from nav2_msgs.msg import Costmap, Route
from nav2_msgs.srv import (
    ClearCostmapAroundRobot,
    ClearCostmapExceptRegion,
    ClearEntireCostmap,
    GetCostmap,
    LoadMap,
    ManageLifecycleNodes,
)
from nav_msgs.msg import Goals, Path
from rclpy.action import ActionClient
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.waitable import Waitable
from std_msgs.msg import Header

from tb4.core.geometry import same_pose
from tb4.core.waits import wait_until
from tb4.navigator._clients import ClientSetup
from tb4.navigator._goals import check_flag, check_geo_poses, check_loops, fill_route_goal, seconds_msg
from tb4.navigator._services import ServiceCaller
from tb4.navigator._signals import watch_signals
from tb4.navigator._task_client import TaskClient, TaskSlot, rejected_code
from tb4.navigator._validate import check_name, check_number, check_path, check_pose_stamped, check_poses
from tb4.navigator.results import RunningTask, TaskResult, status_name
from tb4.navigator.timeouts import DEFAULT_TIMEOUTS, NavigatorTimeout, NavigatorTimeouts
from tb4.processes import abandoned_ports_watched
from tb4.ros.action_client import BUILT_LAST
from tb4.ros.background import BackgroundSpinner, spinner_executor
from tb4.ros.convert import pose_to_tuple
from tb4.wire import get_optional, set_poses, set_supported

__all__ = ["BasicNavigator", "TaskResult", "RunningTask", "NAV2_ACTIONS", "AMCL_POSE_QOS", "COSTMAP_SERVICES"]

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


AMCL_POSE_QOS = QoSProfile(
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
)

_MANAGE_TYPE = "nav2_msgs/srv/ManageLifecycleNodes"

_STATE_POLL = 0.5  # seconds between get_state calls (upstream: 2 s)

_REPUBLISH = 1.0  # seconds between initial pose publications while waiting for amcl_pose

_FIRST_REPUBLISH = 0.3  # the first may be lost while discovery completes on the localizer's side

INVALID_REQUEST = "Request type fields were invalid!"

_UINT16_MAX = 0xFFFF

COSTMAP_SERVICES: dict[str, Any] = {
    "map_server/load_map": LoadMap,
    "global_costmap/clear_entirely_global_costmap": ClearEntireCostmap,
    "local_costmap/clear_entirely_local_costmap": ClearEntireCostmap,
    "local_costmap/clear_costmap_except_region": ClearCostmapExceptRegion,
    "local_costmap/clear_costmap_around_robot": ClearCostmapAroundRobot,
    "global_costmap/get_costmap": GetCostmap,
    "local_costmap/get_costmap": GetCostmap,
}

_LOAD_MAP_REASONS = {
    LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST: "Map does not exist",
    LoadMap.Response.RESULT_INVALID_MAP_DATA: "Invalid map data",
    LoadMap.Response.RESULT_INVALID_MAP_METADATA: "Invalid map metadata",
    LoadMap.Response.RESULT_UNDEFINED_FAILURE: "Undefined failure",
}


class _SpinsWhenBuilt(type):
    """Starts the navigator's executor thread after the outermost __init__ returned, so no thread ever sees a
    half-built navigator (rclpy registers an action client with its node before it finishes building it)."""

    def __call__(cls, *args: Any, **kwargs: Any) -> Any:
        navigator = super().__call__(*args, **kwargs)
        navigator._spinner.start()
        return navigator


class BasicNavigator(Node, metaclass=_SpinsWhenBuilt):
    """Upstream-compatible navigator. Extra keyword-only options: `timeouts`, `use_sim_time` (None = automatic).

    Subclasses may create clients and subscriptions in their __init__ freely: spinning starts after it returns
    (or at the first request sent from inside it).

    A goal whose action server goes away ends FAILED (see isTaskComplete): no wait hangs on a dead simulator.

    Signals: a script ends on SIGTERM as on Ctrl-C. rclpy.init's handlers shut ROS down on either; a navigator
    built in the main thread adds a handler under rclpy's (for each signal still at Python's default) that sends
    the cancel of every running goal, waits up to half a second for the answers, then raises in the main thread:
    KeyboardInterrupt for SIGINT, as Python does, and SystemExit(143) for SIGTERM (143 = 128 + 15, the status of
    a process SIGTERM ended; `finally` blocks and atexit handlers run, `except Exception` does not catch it). A
    navigator built in another thread, or under a SIGTERM handler of the user's, leaves the handlers alone; its
    waits then raise rclpy's ExternalShutdownException once they find the context shut down, after sending the
    cancels.

    Raises:
        ValueError, TypeError: a bad node name, namespace, `timeouts` or `use_sim_time`.
    """

    timeouts: NavigatorTimeouts
    _tasks: TaskClient
    _calls: ServiceCaller
    #: status of the last one-shot call (getPath, smoothPath, getRoute...); upstream kept it in `status`,
    #: clobbering the running task's
    last_call_status: int | None = None
    initial_pose: PoseStamped
    initial_pose_received: bool
    _amcl_received: threading.Event
    _initial_pose_published_at: float
    _last_amcl_pose: tuple[float, float, float] | None
    _awaited_pose: tuple[float, float, float] | None  # setInitialPose's: only amcl_pose at it counts

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
        with abandoned_ports_watched():  # a script's first node makes its process's DDS participant
            super().__init__(node_name=node_name, namespace=namespace)
        self.timeouts = timeouts or DEFAULT_TIMEOUTS
        try:
            executor = spinner_executor(self.context)
        except ValueError:
            super().destroy_node()
            raise
        self._destroyed = False
        # Started by _SpinsWhenBuilt once construction is complete.
        self._spinner = BackgroundSpinner(
            self,
            executor=executor,
            name=f"navigator-spin-{node_name}",
            spin_timeout=0.05,
            on_error=self._log_executor_error,
            adopt=True,
            stop_at_exit=True,
        )
        self._clock_undecided = False  # automatic sim-time detection still looking for /clock (see _configure_clock)
        clients = ClientSetup(
            self,
            lambda: self.timeouts,
            self._before_request,
            self._spinner.paused,
            check_context=lambda what: self._tasks.check_context(what),
        )
        self._tasks = TaskClient(clients)
        self._calls = ServiceCaller(clients)
        for name, action_type in NAV2_ACTIONS.items():
            self._tasks.add(action_type, name)
        self._setup_localization()
        self._setup_costmap_clients()
        self._configure_clock(use_sim_time)
        watch_signals(self)

    def destroyNode(self) -> None:
        self.destroy_node()

    def destroy_node(self) -> None:
        if getattr(self, "_destroyed", True) is False:
            self._destroyed = True
            self._spinner.stop()
            self._tasks.destroy()
            self._calls.destroy()
        super().destroy_node()

    # ================================================================================================
    # Upstream's public methods, in robot_navigator.py's order
    # ================================================================================================

    def setInitialPose(self, initial_pose: PoseStamped) -> None:
        """Tell the localizer where the robot is (published on `initialpose`).

        Args:
            initial_pose: the robot's pose in the map frame.

        Raises:
            ValueError, TypeError: not a usable PoseStamped (NaN, a zero quaternion, a wrong type).
        """
        check_pose_stamped(initial_pose, "initial_pose")
        self.clearLastError()
        self._awaited_pose = pose_to_tuple(initial_pose.pose)
        self.initial_pose_received = False
        self._amcl_received.clear()
        self.initial_pose = initial_pose
        self._setInitialPose()

    def goThroughPoses(self, poses: Goals | list[PoseStamped], behavior_tree: str = "") -> RunningTask | None:
        """Navigate through every pose in order (NavigateThroughPoses). Kilted's own code calls len() on the
        Goals; we do what it meant.

        Args:
            poses: a nav_msgs/Goals (Kilted) or a list of PoseStamped (Jazzy, Humble).
            behavior_tree: a behavior tree for the navigator to use ("" for its default).

        Returns:
            The task (follow it with isTaskComplete(task=...)), or None when the goal was rejected (getTaskError
            says why).

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
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
        """Navigate to `pose` (NavigateToPose).

        Args:
            pose: the goal in the map frame.
            behavior_tree: a behavior tree for the navigator to use ("" for its default).

        Returns:
            The task (follow it with isTaskComplete(task=...)), or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
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
        """Visit each waypoint in turn (FollowWaypoints); feedback.current_waypoint tells which.

        Args:
            poses: the waypoints, in the map frame.
            number_of_loops: how many times to go round again after the first time (the goal's own field).
            goal_index: the waypoint to start at.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        checked = check_poses(poses, "poses")
        check_loops(number_of_loops, goal_index, len(checked))
        self.info(f"Following {len(checked)} goals....")
        goal = FollowWaypoints.Goal(poses=checked, number_of_loops=number_of_loops, goal_index=goal_index)
        rejected = f"Following {len(checked)} waypoints request was rejected!"
        return self._startTask("follow_waypoints", goal, rejected, RunningTask.FOLLOW_WAYPOINTS)

    def followGpsWaypoints(
        self, gps_poses: list[GeoPose], number_of_loops: int = 0, goal_index: int = 0
    ) -> RunningTask | None:
        """Visit each GPS waypoint in turn (FollowGPSWaypoints).

        Args:
            gps_poses: geographic_msgs/GeoPose waypoints (latitude, longitude).
            number_of_loops: how many times to go round again after the first time.
            goal_index: the waypoint to start at.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        checked = check_geo_poses(gps_poses)
        check_loops(number_of_loops, goal_index, len(checked))
        self.info(f"Following {len(checked)} gps goals....")
        goal = FollowGPSWaypoints.Goal(gps_poses=checked, number_of_loops=number_of_loops, goal_index=goal_index)
        rejected = f"Following {len(checked)} gps waypoints request was rejected!"
        return self._startTask("follow_gps_waypoints", goal, rejected, RunningTask.FOLLOW_GPS_WAYPOINTS)

    def spin(
        self, spin_dist: float = 1.57, time_allowance: float = 10, disable_collision_checks: bool = False
    ) -> RunningTask | None:
        """Rotate in place (the Spin behavior).

        Args:
            spin_dist: the angle in radians, counter-clockwise positive.
            time_allowance: seconds the behavior may take.
            disable_collision_checks: turn the behavior's collision checks off (Kilted's field).

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
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
        """Drive straight backwards (the BackUp behavior).

        Args:
            backup_dist: metres to back up.
            backup_speed: metres per second.
            time_allowance: seconds the behavior may take.
            disable_collision_checks: turn the behavior's collision checks off (Kilted's field).

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        goal = self._straight_goal(BackUp, (backup_dist, "backup_dist"), (backup_speed, "backup_speed"), time_allowance)
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
        """Drive straight ahead (the DriveOnHeading behavior).

        Args:
            dist: metres to drive.
            speed: metres per second.
            time_allowance: seconds the behavior may take.
            disable_collision_checks: turn the behavior's collision checks off (Kilted's field).

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        goal = self._straight_goal(DriveOnHeading, (dist, "dist"), (speed, "speed"), time_allowance)
        self._collision_checks(goal, disable_collision_checks)
        self.info(f"Drive {goal.target.x} m on heading at {goal.speed} m/s....")
        return self._startTask(
            "drive_on_heading", goal, "Drive On Heading request was rejected!", RunningTask.DRIVE_ON_HEADING
        )

    def assistedTeleop(self, time_allowance: float = 30) -> RunningTask | None:
        """Let teleop commands (cmd_vel_teleop) through collision checking (the AssistedTeleop behavior).

        Args:
            time_allowance: seconds the behavior runs.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        goal = AssistedTeleop.Goal(time_allowance=seconds_msg(time_allowance, "time_allowance"))
        self.info("Running 'assisted_teleop'....")
        return self._startTask(
            "assisted_teleop", goal, "Assisted Teleop request was rejected!", RunningTask.ASSISTED_TELEOP
        )

    def followPath(self, path: Path, controller_id: str = "", goal_checker_id: str = "") -> RunningTask | None:
        """Follow a given path with the controller (FollowPath).

        Args:
            path: the path, in the map frame.
            controller_id: the controller plugin to use ("" for the only one).
            goal_checker_id: the goal checker plugin to use ("" for the only one).

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        check_path(path)
        check_name(controller_id, "controller_id")
        check_name(goal_checker_id, "goal_checker_id")
        self.info("Executing path...")
        goal = FollowPath.Goal(path=path, controller_id=controller_id, goal_checker_id=goal_checker_id)
        return self._startTask("follow_path", goal, "FollowPath goal was rejected!", RunningTask.FOLLOW_PATH)

    def dockRobotByPose(
        self, dock_pose: PoseStamped, dock_type: str = "", nav_to_dock: bool = True
    ) -> RunningTask | None:
        """Dock at the dock found at a pose (DockRobot with use_dock_id false).

        Args:
            dock_pose: where the dock is.
            dock_type: the dock's plugin type ("" when the server has one).
            nav_to_dock: drive to the dock's staging pose first.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        check_pose_stamped(dock_pose, "dock_pose")
        check_name(dock_type, "dock_type")
        goal = DockRobot.Goal(
            use_dock_id=False, dock_pose=dock_pose, dock_type=dock_type, navigate_to_staging_pose=bool(nav_to_dock)
        )
        p = dock_pose.pose.position
        self.info(f"Docking at pose: ({p.x}, {p.y}) in '{dock_pose.header.frame_id}'...")
        return self._startTask("dock_robot", goal, "DockRobot request was rejected!", RunningTask.DOCK_ROBOT)

    def dockRobotByID(self, dock_id: str, nav_to_dock: bool = True) -> RunningTask | None:
        """Dock at a dock of the docking server's database (DockRobot by id).

        Args:
            dock_id: the dock's id in the database.
            nav_to_dock: drive to the dock's staging pose first.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        check_name(dock_id, "dock_id")
        if not dock_id:
            raise ValueError("dock_id is empty: give the id of a dock in the docking server's database")
        goal = DockRobot.Goal(use_dock_id=True, dock_id=dock_id, navigate_to_staging_pose=bool(nav_to_dock))
        self.info(f"Docking at dock ID: {dock_id}...")
        return self._startTask("dock_robot", goal, "DockRobot request was rejected!", RunningTask.DOCK_ROBOT)

    def undockRobot(self, dock_type: str = "") -> RunningTask | None:
        """Undock from the current dock (UndockRobot).

        Args:
            dock_type: the dock's plugin type; only needed when the server does not know which dock it is on.

        Returns:
            The task, or None when the goal was rejected.

        Raises:
            ValueError, TypeError: an argument that is no usable value (NaN, a wrong type, an empty list...), before
                anything is sent.
            NavigatorTimeout: the action server was not found, or did not answer the goal, within the navigator's
                timeouts.
        """
        check_name(dock_type, "dock_type")
        self.info(f"Undocking from dock of type: {dock_type}...")
        goal = UndockRobot.Goal(dock_type=dock_type)
        return self._startTask("undock_robot", goal, "UndockRobot request was rejected!", RunningTask.UNDOCK_ROBOT)

    def cancelTask(self) -> None:
        """Cancel the running tasks (the main one and a tracked route); their results then read CANCELED.

        A task whose server went away ends FAILED instead (see isTaskComplete). Once the ROS context is shut down
        (after SIGINT or SIGTERM) the spin thread has ended: the cancels are sent and their answers taken by hand,
        for at most half a second in all.

        Raises:
            NavigatorTimeout: a server did not answer the cancel within `timeouts.response`.
        """
        self.info("Canceling current task.")
        self._tasks.cancel()

    def isTaskComplete(self, task: RunningTask | None = RunningTask.NONE) -> bool:
        """Whether the task finished. Returns as soon as the result arrives; while the task runs it waits at most
        `timeouts.task_poll` seconds, so polling loops do not spin the CPU.

        It also checks, cheaply, that the task's action server is still there. A task whose server went away ends
        FAILED (status ABORTED) within seconds, getTaskError() giving the action's UNKNOWN code and what happened,
        e.g. "navigate_to_pose: the action server went away (its node left the ROS graph) while the goal was
        active": at once when the server's node leaves the ROS graph, and after `timeouts.server_lost` seconds
        when the server answers nothing at all, not even the request every live server answers at once (a process
        killed hard stays in the graph for its DDS lease, 20 s with Fast DDS). Its cancel is sent all the same.

        Args:
            task: what the task method returned (Kilted); the default asks about the current task.

        Returns:
            True once the task finished (succeeded, failed, canceled or lost) or when none runs.

        Raises:
            ExternalShutdownException: the ROS context was shut down (rclpy's SIGINT/SIGTERM handler) and no
                handler of ours ended the script first (see the class docstring); the goal's cancel was sent.
        """
        if task is None:
            self.error("Task is None (its goal was rejected): nothing to wait for")
            return True
        slot = self._slot(task)
        done = self._tasks.is_complete(self.timeouts.task_poll, slot)
        if done and slot.result_future is not None:
            if self.getResult() == TaskResult.SUCCEEDED:
                self.debug("Task succeeded!")
            else:
                self.debug(f"Task failed with {self._tasks.status_text()}")
        return done

    def getFeedback(self, task: RunningTask | None = RunningTask.NONE) -> Any:
        """The task's feedback.

        Args:
            task: what the task method returned; the default is the current main task.

        Returns:
            The main task's latest feedback (None before the first); for COMPUTE_AND_TRACK_ROUTE, the oldest route
            feedback not yet read (None when all were read).
        """
        if task is None:
            return None
        slot = self._slot(task)
        if slot is self._tasks.route:
            return slot.pop_feedback()
        return slot.feedback

    def getResult(self) -> TaskResult:
        """How the task isTaskComplete last saw finish ended.

        Returns:
            SUCCEEDED, CANCELED or FAILED once complete; UNKNOWN while running, after a rejection, or before any
            task.
        """
        return self._tasks.task_result()

    # --- the task error, shared by tasks and one-shot calls as upstream does -------------------------------------
    def clearTaskError(self) -> None:
        """Forget the last error: getTaskError() reads (0, '') until something fails again."""
        self._tasks.error = (0, "")

    def setTaskError(self, error_code: int, error_msg: str) -> None:
        """Record an error as getTaskError() reports it (upstream's scripts call this for their own failures).

        Args:
            error_code: the code (Nav2's, or the script's own).
            error_msg: what happened.

        Raises:
            TypeError: `error_code` is not an int.
        """
        if isinstance(error_code, bool) or not isinstance(error_code, int):
            raise TypeError(f"error_code must be an int, got {type(error_code).__name__}")
        self._tasks.error = (error_code, str(error_msg))

    def getTaskError(self) -> tuple[int, str]:
        """The last failed task's or call's error.

        Returns:
            (error_code, error_msg) with Nav2's code; (0, '') after a success.
        """
        return self._tasks.error

    def waitUntilNav2Active(self, navigator: str = "bt_navigator", localizer: str = "amcl") -> None:
        """Wait until the localizer and the navigator report 'active' (and amcl has a pose).

        After setInitialPose, amcl has a pose once it reports that one on `amcl_pose` (the latched estimate from
        before does not count); the pose is sent again until it does.

        Args:
            navigator: the navigator's lifecycle node.
            localizer: the localizer's node ("robot_localization" is not a lifecycle node and is not waited for).

        Raises:
            NavigatorTimeout: a node was not active, or amcl gave no pose, within the navigator's timeouts.
        """
        check_name(navigator, "navigator")
        check_name(localizer, "localizer")
        if localizer != "robot_localization":  # not a lifecycle node
            self._waitForNodeToActivate(localizer)
        if localizer == "amcl":
            self._waitForInitialPose()
        self._waitForNodeToActivate(navigator)
        self.info("Nav2 is ready for use!")

    def getPath(
        self, start: PoseStamped | None, goal: PoseStamped, planner_id: str = "", use_start: bool = False
    ) -> Path | None:
        """Plan a path (ComputePathToPose).

        Args:
            start: where the path starts (used only with `use_start`; else the robot's pose).
            goal: where it ends.
            planner_id: the planner plugin ("" for the only one).
            use_start: plan from `start` instead of the robot's pose.

        Returns:
            The path, or None when planning failed (getTaskError says why).
        """
        return self._finish(self._getPathImpl(start, goal, planner_id, use_start), "Getting path")

    def getPathThroughPoses(
        self, start: PoseStamped | None, goals: Goals | list[PoseStamped], planner_id: str = "", use_start: bool = False
    ) -> Path | None:
        """Plan a path through every pose in order (ComputePathThroughPoses).

        Args:
            start: where the path starts (used only with `use_start`).
            goals: a list of PoseStamped or a nav_msgs/Goals.
            planner_id: the planner plugin ("" for the only one).
            use_start: plan from `start` instead of the robot's pose.

        Returns:
            The path, or None when planning failed.
        """
        return self._finish(
            self._getPathThroughPosesImpl(start, goals, planner_id, use_start), "Getting path through poses"
        )

    def getRoute(
        self, start: int | PoseStamped, goal: int | PoseStamped, use_start: bool = False
    ) -> list[Path | Route] | None:
        """Compute a route on the route graph (ComputeRoute).

        Args:
            start: a graph node id, or a pose.
            goal: a graph node id, or a pose.
            use_start: start from `start` instead of the robot's pose.

        Returns:
            [the dense nav_msgs/Path, the sparse nav2_msgs/Route], or None (the task error set) on failure.
        """
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
        each rerouted feedback.path to followPath, as Nav2's example does.

        Args:
            start: a graph node id, or a pose.
            goal: a graph node id, or a pose.
            use_start: start from `start` instead of the robot's pose.

        Returns:
            The task (RunningTask.COMPUTE_AND_TRACK_ROUTE), or None when the request was invalid or rejected.
        """
        self.clearTaskError()
        request = ComputeAndTrackRoute.Goal()
        if not fill_route_goal(request, start, goal, use_start):
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

    def smoothPath(
        self, path: Path, smoother_id: str = "", max_duration: float = 2.0, check_for_collision: bool = False
    ) -> Path | None:
        """Smooth a path (SmoothPath).

        Args:
            path: the path to smooth.
            smoother_id: the smoother plugin ("" for the only one).
            max_duration: seconds the smoother may take.
            check_for_collision: fail when the smoothed path would collide.

        Returns:
            The smoothed path, or None when smoothing failed.
        """
        return self._finish(
            self._smoothPathImpl(path, smoother_id, max_duration, check_for_collision), "Smoothing path"
        )

    def changeMap(self, map_filepath: str | os.PathLike[str]) -> bool:
        """Ask the map server to load another map (map_server/load_map).

        Args:
            map_filepath: the map's YAML file, as the map server sees it.

        Returns:
            True on success; False with the last error set (the map server's reason) otherwise.

        Raises:
            TypeError, ValueError: not a path, or an empty one.
            NavigatorTimeout: the map server was not found or did not answer in time.
        """
        if not isinstance(map_filepath, (str, os.PathLike)):
            raise TypeError(f"map_filepath must be a path string, got {type(map_filepath).__name__}")
        path = os.fspath(map_filepath)
        if not path:
            raise ValueError("map_filepath is empty")
        self.clearLastError()
        request = LoadMap.Request(map_url=path)
        response = self._calls.call(LoadMap, "map_server/load_map", request, response_timeout=self.timeouts.result)
        if response.result != LoadMap.Response.RESULT_SUCCESS:
            reason = _LOAD_MAP_REASONS.get(response.result, "Unknown")
            self.setLastError(int(response.result), f"{reason}: {path}")
            self.error(f"Change map request failed: {reason} ({path})!")
            return False
        self.info("Change map request was successful!")
        return True

    def clearAllCostmaps(self) -> None:
        """Clear the local and the global costmap."""
        self.clearLastError()
        self.clearLocalCostmap()
        self.clearGlobalCostmap()

    def clearLocalCostmap(self) -> None:
        self._calls.call(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap", ClearEntireCostmap.Request())

    def clearGlobalCostmap(self) -> None:
        self._calls.call(
            ClearEntireCostmap, "global_costmap/clear_entirely_global_costmap", ClearEntireCostmap.Request()
        )

    def clearCostmapExceptRegion(self, reset_distance: float) -> None:
        """Clear the local costmap outside a square around the robot.

        Args:
            reset_distance: the square's side in metres (not negative).
        """
        d = check_number(reset_distance, "reset_distance", non_negative=True)
        request = ClearCostmapExceptRegion.Request(reset_distance=d)
        self._calls.call(ClearCostmapExceptRegion, "local_costmap/clear_costmap_except_region", request)

    def clearCostmapAroundRobot(self, reset_distance: float) -> None:
        """Clear the local costmap inside a square around the robot.

        Args:
            reset_distance: the square's side in metres (not negative).
        """
        d = check_number(reset_distance, "reset_distance", non_negative=True)
        request = ClearCostmapAroundRobot.Request(reset_distance=d)
        self._calls.call(ClearCostmapAroundRobot, "local_costmap/clear_costmap_around_robot", request)

    def getGlobalCostmap(self) -> Costmap:
        """The global costmap.

        Returns:
            A nav2_msgs/Costmap; wrap it in PyCostmap2D to query cells.
        """
        return self._calls.call(GetCostmap, "global_costmap/get_costmap", GetCostmap.Request(), idempotent=True).map

    def getLocalCostmap(self) -> Costmap:
        """The local (rolling) costmap.

        Returns:
            A nav2_msgs/Costmap.
        """
        return self._calls.call(GetCostmap, "local_costmap/get_costmap", GetCostmap.Request(), idempotent=True).map

    def lifecycleStartup(self) -> bool:
        """STARTUP on every lifecycle manager found by discovery.

        Returns:
            True when every manager started its nodes.
        """
        self.info("Starting up lifecycle nodes based on lifecycle_manager.")
        ok = self._manage(ManageLifecycleNodes.Request.STARTUP, "Starting up")
        if ok:
            self.info("Nav2 is ready for use!")
        return ok

    def lifecycleShutdown(self) -> bool:
        """SHUTDOWN on every lifecycle manager found by discovery.

        Returns:
            True when every manager shut its nodes down.
        """
        self.info("Shutting down lifecycle nodes based on lifecycle_manager.")
        return self._manage(ManageLifecycleNodes.Request.SHUTDOWN, "Shutting down")

    def info(self, msg: str) -> None:
        self.get_logger().info(msg)

    def warn(self, msg: str) -> None:
        self.get_logger().warning(msg)

    def error(self, msg: str) -> None:
        self.get_logger().error(msg)

    def debug(self, msg: str) -> None:
        self.get_logger().debug(msg)

    # ================================================================================================
    # Beyond upstream: Jazzy-era names, the status name, upstream's error attributes
    # ================================================================================================

    # Jazzy-era names of the same
    def getLastError(self) -> tuple[int, str]:
        return self.getTaskError()

    def setLastError(self, error_code: int, error_msg: str) -> None:
        self.setTaskError(int(error_code), error_msg)

    def clearLastError(self) -> None:
        self.clearTaskError()

    @property
    def last_action_error_code(self) -> int:
        return self._tasks.error[0]

    @property
    def last_action_error_msg(self) -> str:
        return self._tasks.error[1]

    def getTaskStatusName(self) -> str:
        """The task's goal status as a word.

        Returns:
            SUCCEEDED, ABORTED, CANCELED, ..., RUNNING, or REJECTED.
        """
        slot = self._tasks.reported
        if slot.running() and not self._tasks.is_complete(0.0, slot):
            return "RUNNING"
        return status_name(slot.status)

    # ================================================================================================
    # Private helpers of the methods above (set-up, waits, goals, one-shot calls)
    # ================================================================================================

    # --- starting a task -------------------------------------------------------------------------------------------
    def _startTask(
        self, name: str, goal: Any, rejected: str, task: RunningTask, slot: TaskSlot | None = None
    ) -> RunningTask | None:
        """Send `goal` as the running task; `task` if accepted, None (task error: Nav2's UNKNOWN code and
        `rejected`) if the server rejected it."""
        if self._tasks.start(name, goal, slot):
            return task
        code, _ = self._tasks.error
        self.setTaskError(code, rejected)
        self.error(rejected)
        return None

    def _one_shot(self, name: str, goal: Any, action_type: Any, what: str) -> Any:
        """Send a goal, wait for its result (bounded) and return it; a rejection becomes a result carrying the
        action's UNKNOWN code and '`what` was rejected!'. The running tasks are left alone."""
        self.clearTaskError()
        status, result = self._tasks.call(name, goal)
        self.last_call_status = status
        if status is None:
            message = f"{what} was rejected!"
            self.error(message)
            result = action_type.Result()
            # Jazzy's route results have no error_msg: the task error keeps the message for getTaskError()
            set_supported(result, error_code=rejected_code(action_type), error_msg=message)
            self.setTaskError(rejected_code(action_type), message)
        return result

    @staticmethod
    def _straight_goal(action_type: Any, dist: tuple[Any, str], speed: tuple[Any, str], time_allowance: Any) -> Any:
        """A BackUp or DriveOnHeading goal: distance along x, a positive speed, a time allowance (each checked and
        named as the caller's parameter)."""
        return action_type.Goal(
            target=Point(x=check_number(*dist)),
            speed=check_number(*speed, positive=True),
            time_allowance=seconds_msg(time_allowance, "time_allowance"),
        )

    def _collision_checks(self, goal: Any, disable_collision_checks: bool) -> None:
        """Kilted's behaviors can skip collision checks; Jazzy's nav2_msgs has no such field, so they stay on."""
        disable = check_flag(disable_collision_checks, "disable_collision_checks")
        if set_supported(goal, disable_collision_checks=disable) and disable:
            self.warn("disable_collision_checks needs Kilted's nav2_msgs: on this Jazzy build collision checks stay on")

    def _slot(self, task: Any) -> TaskSlot:
        if not isinstance(task, RunningTask):
            raise TypeError(
                f"task must be a RunningTask (what goToPose, spin, ... returned), got {type(task).__name__} ({task!r})"
            )
        return self._tasks.route if task is RunningTask.COMPUTE_AND_TRACK_ROUTE else self._tasks.main

    def _setup_localization(self) -> None:
        self.initial_pose = PoseStamped()
        self.initial_pose.header.frame_id = "map"
        self.initial_pose_received = False
        self._amcl_received = threading.Event()
        self._initial_pose_published_at = -math.inf
        self._last_amcl_pose = None
        self._awaited_pose = None
        self.localization_pose_sub = self.create_subscription(
            PoseWithCovarianceStamped, "amcl_pose", self._amclPoseCallback, AMCL_POSE_QOS
        )
        self.initial_pose_pub = self.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)

    def _amclPoseCallback(self, msg: PoseWithCovarianceStamped) -> None:
        self.debug("Received amcl pose")
        self._last_amcl_pose = pose_to_tuple(msg.pose.pose)
        # After setInitialPose, only an estimate at that pose says the localizer has it: amcl_pose is latched, and
        # the estimate from before (at the dock, or a run ago) comes at once, whether or not the pose arrived
        # (upstream takes any; a pose sent before the localizer matched this writer is then lost without a word).
        awaited = self._awaited_pose
        if awaited is not None and not same_pose(self._last_amcl_pose, awaited):
            return
        self.initial_pose_received = True
        self._amcl_received.set()

    def _setInitialPose(self) -> None:
        # A message published before discovery matched a reader is lost to that reader: wait (bounded) until every
        # reader the graph shows (the localizer, a recorder, a viewer) has matched, and one of another node has (a
        # TurtleBot4Navigator reads `initialpose` itself, and its own reader matches at once).
        publisher = self.initial_pose_pub

        def all_matched() -> bool:
            readers = self.get_subscriptions_info_by_topic(publisher.topic_name)
            mine = (self.get_name(), self.get_namespace())
            others = [r for r in readers if (r.node_name, r.node_namespace) != mine]
            return bool(others) and publisher.get_subscription_count() >= len(readers)

        wait_until(all_matched, min(2.0, self.timeouts.server))
        msg = PoseWithCovarianceStamped()
        msg.pose.pose = self.initial_pose.pose
        msg.header.frame_id = self.initial_pose.header.frame_id
        msg.header.stamp = self.initial_pose.header.stamp
        self.info("Publishing Initial Pose")
        self.initial_pose_pub.publish(msg)
        self._initial_pose_published_at = time.monotonic()

    def _waitForNodeToActivate(self, node_name: str) -> None:
        self.debug(f"Waiting for {node_name} to become active..")
        limit = self.timeouts.lifecycle
        deadline = time.monotonic() + limit
        service = f"{node_name}/get_state"
        state = "unknown"
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            try:
                response = self._calls.call(
                    GetState, service, GetState.Request(), server_timeout=remaining, idempotent=True
                )
            except NavigatorTimeout as exc:
                raise NavigatorTimeout(f"{exc} (waiting for '{node_name}' to become active)") from None
            state = response.current_state.label
            self.debug(f"Result of get_state: {state}")
            if state == "active":
                return
            time.sleep(min(_STATE_POLL, max(0.0, deadline - time.monotonic())))
        message = f"'{node_name}' did not become active within {limit:g} s (last state: '{state}')"
        self.error(message)
        raise NavigatorTimeout(message)

    def _waitForInitialPose(self) -> None:
        self._ensure_spun()
        limit = self.timeouts.localization
        deadline = time.monotonic() + limit
        published = 1 if self._initial_pose_published_at > -math.inf else 0
        while not self.initial_pose_received:
            self._tasks.check_context("amcl_pose")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                p = self.initial_pose.pose.position
                last = self._last_amcl_pose
                heard = "none came" if last is None else f"the last was at ({last[0]:.2f}, {last[1]:.2f})"
                message = (
                    f"no 'amcl_pose' at the initial pose ({p.x:.2f}, {p.y:.2f}) after {limit:g} s ({heard}) although "
                    f"it was published {published} times on 'initialpose' in namespace '{self.get_namespace()}' — "
                    "is the localizer running and is the pose inside the map (frame 'map')?"
                )
                self.error(message)
                raise NavigatorTimeout(message)
            period = _FIRST_REPUBLISH if published <= 1 else _REPUBLISH
            since = time.monotonic() - self._initial_pose_published_at
            if since >= period:  # setInitialPose has just published: give that one its chance first
                self.info("Setting initial pose")
                self._setInitialPose()
                published += 1
                since = 0.0
            self.info("Waiting for amcl_pose to be received")
            self._amcl_received.wait(min(period - since, remaining))

    # --- lifecycle managers ------------------------------------------------------------------------------------
    def _lifecycle_managers(self) -> list[str]:
        """Every ManageLifecycleNodes service in our namespace (upstream took every robot's)."""
        ns = self.get_namespace().rstrip("/")

        def find() -> list[str]:
            return sorted(
                name
                for name, types in self.get_service_names_and_types()
                if _MANAGE_TYPE in types and (not ns or name.startswith(ns + "/"))
            )

        found: list[str] = []

        def any_found() -> bool:
            found[:] = find()
            return bool(found)

        if not wait_until(any_found, self.timeouts.server, period=0.1):
            raise NavigatorTimeout(
                f"no {_MANAGE_TYPE} service in namespace '{self.get_namespace()}' after {self.timeouts.server:g} s"
                " — is Nav2 (its lifecycle managers) running?"
            )
        return found

    def _manage(self, command: int, verb: str) -> bool:
        ok = True
        for name in self._lifecycle_managers():
            self.info(f"{verb} {name}")
            request = ManageLifecycleNodes.Request(command=command)
            response = self._calls.call(ManageLifecycleNodes, name, request, response_timeout=self.timeouts.result)
            if not response.success:
                self.error(f"{name} reported failure")
                ok = False
        return ok

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

    def _getRouteImpl(self, start: int | PoseStamped, goal: int | PoseStamped, use_start: bool = False) -> Any:
        """The whole ComputeRoute result (planning_time, path, route, error_code, error_msg)."""
        request = ComputeRoute.Goal()
        if not fill_route_goal(request, start, goal, use_start):
            self.error("Invalid start and goal types. Must be PoseStamped for pose or int for ID")
            self.last_call_status = None
            result = ComputeRoute.Result(error_code=rejected_code(ComputeRoute))
            set_supported(result, error_msg=INVALID_REQUEST)  # Kilted only: the task error keeps it in either format
            self.setTaskError(result.error_code, INVALID_REQUEST)
            return result
        self.info("Getting route...")
        return self._one_shot("compute_route", request, ComputeRoute, "Get route")

    def _setup_costmap_clients(self) -> None:
        for name, srv_type in COSTMAP_SERVICES.items():
            self._calls.add(srv_type, name)

    # ================================================================================================
    # Node plumbing (the executor thread, the clock) and upstream's attributes
    # ================================================================================================
    def _log_executor_error(self, exc: Exception) -> None:
        self.get_logger().error(f"navigator executor: {type(exc).__name__}: {exc}")

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
        """The node's waitables, less action clients rclpy has registered but not finished building (BUILT_LAST comes
        last): an executor, ours or the user's, never touches a half-built client, whoever creates it."""
        for waitable in super().waitables:
            if isinstance(waitable, ActionClient) and BUILT_LAST not in vars(waitable):
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
            self._tasks.check_context(f"the end of sleep({seconds})")
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
