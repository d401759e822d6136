"""BasicNavigator: Nav2 Simple Commander's API (Jazzy/Kilted) with bounded waits and event-driven completion.

    rclpy.init()
    nav = BasicNavigator()
    nav.setInitialPose(pose); nav.waitUntilNav2Active()
    nav.goToPose(goal)
    while not nav.isTaskComplete():
        feedback = nav.getFeedback()
    print(nav.getResult(), nav.getTaskError())

The navigator is an rclpy Node spun by its own daemon thread; it may also be added to the user's executor.
Concerns live in mixins: localization/lifecycle (_localization), costmaps (_costmaps), planning (_planning);
action goals and the current task in _task_client.TaskClient.
"""

from __future__ import annotations

import time
from typing import Any

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, PoseStamped
from nav2_msgs.action import (
    AssistedTeleop,
    BackUp,
    ComputePathThroughPoses,
    ComputePathToPose,
    DockRobot,
    DriveOnHeading,
    FollowPath,
    FollowWaypoints,
    NavigateThroughPoses,
    NavigateToPose,
    SmoothPath,
    Spin,
    UndockRobot,
)
from nav_msgs.msg import Goals, Path
from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.parameter import Parameter

from tb4.navigator._costmaps import CostmapMixin
from tb4.navigator._localization import LocalizationMixin
from tb4.navigator._planning import PlanningMixin
from tb4.navigator._services import ServiceCaller
from tb4.navigator._spinner import BackgroundSpinner, wait_until
from tb4.navigator._task_client import TaskClient
from tb4.navigator._validate import check_name, check_number, check_path, check_pose_stamped, check_poses
from tb4.navigator.results import TaskResult, status_name
from tb4.navigator.timeouts import DEFAULT_TIMEOUTS, NavigatorTimeout, NavigatorTimeouts

__all__ = ["BasicNavigator", "TaskResult", "NAV2_ACTIONS"]

#: Relative action names and types, as Nav2 serves them.
NAV2_ACTIONS: dict[str, Any] = {
    "navigate_to_pose": NavigateToPose,
    "navigate_through_poses": NavigateThroughPoses,
    "follow_waypoints": FollowWaypoints,
    "follow_path": FollowPath,
    "compute_path_to_pose": ComputePathToPose,
    "compute_path_through_poses": ComputePathThroughPoses,
    "smooth_path": SmoothPath,
    "spin": Spin,
    "backup": BackUp,
    "drive_on_heading": DriveOnHeading,
    "assisted_teleop": AssistedTeleop,
    "dock_robot": DockRobot,
    "undock_robot": UndockRobot,
}


def _seconds(value: Any, what: str) -> Duration:
    seconds = check_number(value, what, positive=True)
    whole = int(seconds)
    return Duration(sec=whole, nanosec=int(round((seconds - whole) * 1e9)) % 1_000_000_000)


class BasicNavigator(PlanningMixin, CostmapMixin, LocalizationMixin):
    """Upstream-compatible navigator. Extra keyword-only options: `timeouts`, `use_sim_time` (None = automatic)."""

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
        self._tasks = TaskClient(self, lambda: self.timeouts, self._ensure_spun)
        self._calls = ServiceCaller(self, lambda: self.timeouts, self._ensure_spun)
        for name, action_type in NAV2_ACTIONS.items():
            self._tasks.add(action_type, name)
        self._setup_localization()
        self._setup_costmap_clients()
        self._destroyed = False
        self._spinner = BackgroundSpinner(self)
        self._configure_clock(use_sim_time)

    def _ensure_spun(self) -> None:
        spinner = getattr(self, "_spinner", None)
        if spinner is not None:
            spinner.ensure_spun()

    def _configure_clock(self, use_sim_time: bool | None) -> None:
        """Follow the simulator's /clock when one publishes it (waits then scale with accelerated time)."""
        if use_sim_time is None:
            limit = self.timeouts.clock_discovery
            use_sim_time = limit > 0 and wait_until(lambda: self.count_publishers("/clock") > 0, limit)
        if use_sim_time:
            self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
            self.debug("Using the simulator's /clock")

    @property
    def default_callback_group(self) -> CallbackGroup:
        return self._navigator_group

    @property
    def uses_sim_time(self) -> bool:
        return bool(self.get_parameter("use_sim_time").value)

    def sleep(self, seconds: float) -> None:
        """Wait `seconds` on the node's clock: simulated seconds under the simulator, so a charging wait of 15 s
        passes as fast as the simulation runs. NavigatorTimeout if that clock stops (no /clock for
        `timeouts.response` wall seconds)."""
        duration = check_number(seconds, "seconds", non_negative=True)
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

    # --- tasks ---------------------------------------------------------------------------------------------------
    def _startTask(self, name: str, goal: Any, rejected: str) -> bool:
        if self._tasks.start(name, goal):
            return True
        self.error(rejected)
        return False

    def goToPose(self, pose: PoseStamped, behavior_tree: str = "") -> bool:
        """Navigate to `pose` (NavigateToPose). True if the goal was accepted; follow it with isTaskComplete()."""
        check_pose_stamped(pose, "pose")
        check_name(behavior_tree, "behavior_tree")
        p = pose.pose.position
        self.info(f"Navigating to goal: {p.x} {p.y}...")
        goal = NavigateToPose.Goal(pose=pose, behavior_tree=behavior_tree)
        return self._startTask("navigate_to_pose", goal, f"Goal to {p.x} {p.y} was rejected!")

    def goThroughPoses(self, poses: list[PoseStamped] | Goals, behavior_tree: str = "") -> bool:
        """Navigate through every pose in order (NavigateThroughPoses); a list or a nav_msgs/Goals."""
        checked = check_poses(poses, "poses")
        check_name(behavior_tree, "behavior_tree")
        goals = Goals(goals=checked)
        goals.header.frame_id = checked[0].header.frame_id
        self.info(f"Navigating with {len(checked)} goals....")
        goal = NavigateThroughPoses.Goal(poses=goals, behavior_tree=behavior_tree)
        return self._startTask("navigate_through_poses", goal, f"Goal with {len(checked)} poses was rejected!")

    def followWaypoints(self, poses: list[PoseStamped], number_of_loops: int = 0, goal_index: int = 0) -> bool:
        """Visit each waypoint in turn (FollowWaypoints); feedback.current_waypoint tells which."""
        checked = check_poses(poses, "poses")
        for value, what in ((number_of_loops, "number_of_loops"), (goal_index, "goal_index")):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{what} must be a non-negative int, got {value!r}")
        if goal_index >= len(checked):
            raise ValueError(f"goal_index {goal_index} is out of range for {len(checked)} waypoints")
        self.info(f"Following {len(checked)} goals....")
        goal = FollowWaypoints.Goal(poses=checked, number_of_loops=number_of_loops, goal_index=goal_index)
        return self._startTask("follow_waypoints", goal, f"Following {len(checked)} waypoints request was rejected!")

    def followPath(self, path: Path, controller_id: str = "", goal_checker_id: str = "") -> bool:
        """Follow a given path with the controller (FollowPath)."""
        check_path(path)
        check_name(controller_id, "controller_id")
        check_name(goal_checker_id, "goal_checker_id")
        self.info("Executing path...")
        goal = FollowPath.Goal(path=path, controller_id=controller_id, goal_checker_id=goal_checker_id)
        return self._startTask("follow_path", goal, "Follow path was rejected!")

    def spin(self, spin_dist: float = 1.57, time_allowance: float = 10, disable_collision_checks: bool = False) -> bool:
        """Rotate in place by `spin_dist` radians (counter-clockwise positive)."""
        yaw = check_number(spin_dist, "spin_dist")
        goal = Spin.Goal(
            target_yaw=yaw,
            time_allowance=_seconds(time_allowance, "time_allowance"),
            disable_collision_checks=bool(disable_collision_checks),
        )
        self.info(f"Spinning to angle {goal.target_yaw}....")
        return self._startTask("spin", goal, "Spin request was rejected!")

    def backup(
        self,
        backup_dist: float = 0.15,
        backup_speed: float = 0.025,
        time_allowance: float = 10,
        disable_collision_checks: bool = False,
    ) -> bool:
        """Drive straight backwards `backup_dist` metres at `backup_speed` m/s."""
        dist = check_number(backup_dist, "backup_dist")
        speed = check_number(backup_speed, "backup_speed", positive=True)
        goal = BackUp.Goal(
            target=Point(x=dist),
            speed=speed,
            time_allowance=_seconds(time_allowance, "time_allowance"),
            disable_collision_checks=bool(disable_collision_checks),
        )
        self.info(f"Backing up {goal.target.x} m at {goal.speed} m/s....")
        return self._startTask("backup", goal, "Backup request was rejected!")

    def driveOnHeading(
        self,
        dist: float = 0.15,
        speed: float = 0.025,
        time_allowance: float = 10,
        disable_collision_checks: bool = False,
    ) -> bool:
        """Drive straight ahead `dist` metres at `speed` m/s."""
        distance = check_number(dist, "dist")
        velocity = check_number(speed, "speed", positive=True)
        goal = DriveOnHeading.Goal(
            target=Point(x=distance),
            speed=velocity,
            time_allowance=_seconds(time_allowance, "time_allowance"),
            disable_collision_checks=bool(disable_collision_checks),
        )
        self.info(f"Drive {goal.target.x} m on heading at {goal.speed} m/s....")
        return self._startTask("drive_on_heading", goal, "Drive On Heading request was rejected!")

    def assistedTeleop(self, time_allowance: float = 30) -> bool:
        """Let teleop commands (cmd_vel_teleop) through collision checking for `time_allowance` seconds."""
        goal = AssistedTeleop.Goal(time_allowance=_seconds(time_allowance, "time_allowance"))
        self.info("Running 'assisted_teleop'....")
        return self._startTask("assisted_teleop", goal, "Assisted Teleop request was rejected!")

    def dockRobotByPose(self, dock_pose: PoseStamped, dock_type: str = "", nav_to_dock: bool = True) -> bool:
        """Dock at a dock given by its pose (Nav2 docking_server)."""
        check_pose_stamped(dock_pose, "dock_pose")
        check_name(dock_type, "dock_type")
        goal = DockRobot.Goal(
            use_dock_id=False, dock_pose=dock_pose, dock_type=dock_type, navigate_to_staging_pose=bool(nav_to_dock)
        )
        p = dock_pose.pose.position
        self.info(f"Docking at pose: ({p.x}, {p.y})...")
        return self._startTask("dock_robot", goal, "Docking request was rejected!")

    def dockRobotByID(self, dock_id: str, nav_to_dock: bool = True) -> bool:
        """Dock at a dock of the docking server's database, by id."""
        check_name(dock_id, "dock_id")
        goal = DockRobot.Goal(use_dock_id=True, dock_id=dock_id, navigate_to_staging_pose=bool(nav_to_dock))
        self.info(f"Docking at dock ID: {dock_id}...")
        return self._startTask("dock_robot", goal, "Docking request was rejected!")

    def undockRobot(self, dock_type: str = "") -> bool:
        """Undock (Nav2 docking_server)."""
        check_name(dock_type, "dock_type")
        self.info(f"Undocking from dock of type: {dock_type}...")
        return self._startTask("undock_robot", UndockRobot.Goal(dock_type=dock_type), "Undocking request was rejected!")

    # --- following the current task ------------------------------------------------------------------------------
    def cancelTask(self) -> None:
        """Cancel the current task, if one runs; its result then reads CANCELED."""
        self.info("Canceling current task.")
        self._tasks.cancel()

    def isTaskComplete(self) -> bool:
        """True once the current task finished (or none runs). Returns as soon as the result arrives; while the
        task runs it waits at most `timeouts.task_poll` seconds, so polling loops do not spin the CPU."""
        done = self._tasks.is_complete(self.timeouts.task_poll)
        if done and self._tasks.result_future is not None:
            if self.getResult() == TaskResult.SUCCEEDED:
                self.debug("Task succeeded!")
            else:
                self.debug(f"Task failed with {self._tasks.status_text()}")
        return done

    def getFeedback(self) -> Any:
        """The latest feedback message of the current task (None before the first)."""
        return self._tasks.feedback

    def getResult(self) -> TaskResult:
        """SUCCEEDED / CANCELED / FAILED once complete; UNKNOWN while running, after a rejection, or before a task."""
        return self._tasks.task_result()

    def getTaskStatusName(self) -> str:
        """The current task's goal status as a word (SUCCEEDED, ABORTED, CANCELED, ... or REJECTED)."""
        if self._tasks.result_future is not None and not self._tasks.is_complete(0.0):
            return "RUNNING"
        return status_name(self._tasks.status)
