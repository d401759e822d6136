"""TurtleBot4Navigator: the TurtleBot 4 helpers on top of BasicNavigator (poses from compass directions, the
Create 3 dock/undock actions, blocking start* helpers that print progress, a path drawn with RViz's pose tool).

Differences from upstream, all compatible: failure logs name the real goal status and error; a rejected goal
leaves no stale state; getDockedStatus/dock/undock have timeouts; createPath ends on Enter or end of input.
"""

from __future__ import annotations

import math
import queue
import select
import sys
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Pose, PoseStamped, PoseWithCovarianceStamped, Quaternion
from irobot_create_msgs.action import Dock, Undock
from irobot_create_msgs.msg import DockStatus
from rclpy.qos import qos_profile_sensor_data

from tb4.core.directions import TurtleBot4Directions, direction_from_name
from tb4.core.geometry import yaw_to_quaternion
from tb4.core.units import seconds_of
from tb4.navigator._task_client import TaskSlot
from tb4.navigator._validate import check_number, check_pose_stamped
from tb4.navigator.basic_navigator import BasicNavigator
from tb4.navigator.results import RunningTask, TaskResult, status_name
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts

__all__ = ["TurtleBot4Navigator", "TurtleBot4Directions", "NAVIGATION_TIME_LIMIT"]

NAVIGATION_TIME_LIMIT = 600.0  # seconds of navigation (the server's clock) before start* helpers cancel
_FRESH_DOCK_STATUS = 1.0  # a dock_status younger than this (wall s) answers getDockedStatus at once


class TurtleBot4Navigator(BasicNavigator):
    """BasicNavigator plus the TurtleBot 4 helpers, same names and behaviour as turtlebot4_navigation's."""

    def __init__(
        self,
        namespace: str = "",
        *,
        node_name: str = "basic_navigator",
        timeouts: NavigatorTimeouts | None = None,
        use_sim_time: bool | None = None,
    ) -> None:
        super().__init__(node_name=node_name, namespace=namespace, timeouts=timeouts, use_sim_time=use_sim_time)
        self.is_docked: bool | None = None
        self.creating_path = False
        self._dock_status_event = threading.Event()
        self._dock_status_at = -math.inf
        # After a dock or undock that succeeded (the Create 3's Dock/Undock or Nav2's DockRobot/UndockRobot task),
        # what dock_status must say before getDockedStatus answers; cleared by the first status that says it.
        self._expected_dock: bool | None = None
        self._new_poses: queue.Queue[Pose] = queue.Queue()
        self._dock_status_sub = self.create_subscription(
            DockStatus, "dock_status", self._dockCallback, qos_profile_sensor_data
        )
        self.create_subscription(PoseWithCovarianceStamped, "initialpose", self._poseEstimateCallback, 10)
        self._tasks.add(Dock, "dock")
        self._tasks.add(Undock, "undock")
        self._tasks.on_finished = self._on_task_finished

    # --- poses ---------------------------------------------------------------------------------------------------
    def getPoseStamped(self, position: Sequence[float], rotation: float | str) -> PoseStamped:
        """A PoseStamped in 'map' at [x, y], heading `rotation` degrees (a TurtleBot4Directions or any number)."""
        indexable = hasattr(position, "__len__") and hasattr(position, "__getitem__")  # lists, tuples, arrays
        if isinstance(position, (str, bytes)) or not indexable:
            raise TypeError(f"position must be a list [x, y], got {type(position).__name__}")
        if len(position) != 2:
            raise ValueError(f"position must have 2 values [x, y], got {len(position)}")
        x = check_number(position[0], "position x")
        y = check_number(position[1], "position y")
        if isinstance(rotation, str):
            rotation = direction_from_name(rotation)
        degrees = check_number(rotation, "rotation (degrees)")
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = self.get_clock().now().to_msg()
        pose.pose.position.x = x
        pose.pose.position.y = y
        x, y, z, w = yaw_to_quaternion(math.radians(degrees))
        pose.pose.orientation = Quaternion(x=x, y=y, z=z, w=w)
        return pose

    def stampPose(self, pose: Pose) -> PoseStamped:
        """Wrap a Pose into a PoseStamped in 'map', stamped now."""
        if not isinstance(pose, Pose):
            raise TypeError(f"pose must be a geometry_msgs/Pose, got {type(pose).__name__}")
        stamped = PoseStamped()
        stamped.header.frame_id = "map"
        stamped.header.stamp = self.get_clock().now().to_msg()
        stamped.pose = pose
        return stamped

    def _poseEstimateCallback(self, msg: PoseWithCovarianceStamped) -> None:
        if self.creating_path:
            self._new_poses.put(msg.pose.pose)

    def createPath(self) -> list[PoseStamped]:
        """Collect poses given with RViz's '2D Pose Estimate' tool (topic initialpose) until Enter is pressed."""
        poses: list[PoseStamped] = []
        while not self._new_poses.empty():
            self._new_poses.get_nowait()
        self.creating_path = True
        self.info("Creating a path. Press Enter to finish.")
        self.info('Use the "2D Pose Estimate" tool in Rviz to add a pose to the path.')
        finished = _enter_pressed()
        try:
            while True:
                done = finished()
                while not self._new_poses.empty():
                    poses.append(self.stampPose(self._new_poses.get_nowait()))
                    self.info("Pose added.")
                    self.clearAllCostmaps()
                if done:
                    break
                try:
                    pose = self._new_poses.get(timeout=0.05)
                except queue.Empty:
                    continue
                poses.append(self.stampPose(pose))
                self.info("Pose added.")
                self.clearAllCostmaps()
        except KeyboardInterrupt:
            pass
        finally:
            self.creating_path = False
        self.info("Path created.")
        for i, p in enumerate(poses):
            q = p.pose.orientation
            self.info(
                f"Pose {i} [x,y]=[{p.pose.position.x:.3f},{p.pose.position.y:.3f}] "
                f"[x,y,z,w]=[{q.x:.3f},{q.y:.3f},{q.z:.3f},{q.w:.3f}]"
            )
        return poses

    # --- dock ------------------------------------------------------------------------------------------------------
    def _dockCallback(self, msg: DockStatus) -> None:
        self.is_docked = bool(msg.is_docked)
        self._dock_status_at = time.monotonic()
        if self.is_docked == self._expected_dock:
            self._expected_dock = None
        self._dock_status_event.set()

    def getDockedStatus(self) -> bool:
        """True if the robot sits on its dock (from dock_status); NavigatorTimeout if no status arrives."""
        # A status counts if it is recent and came after the last task's end (a dock that just finished may not be
        # in the status received before it). After a dock or undock that succeeded, it must also say what that
        # action's result said: statuses sent before the robot docked can still be queued when the result is in
        # (a starved client takes one message per wake-up), and the first of them would answer "not docked".
        # Should none agree within the limit, the latest status answers.
        fresh_since = max(time.monotonic() - _FRESH_DOCK_STATUS, self._tasks.finished_at)

        def fresh() -> bool:
            return self.is_docked is not None and self._dock_status_at > fresh_since

        limit = self.timeouts.dock_status
        deadline = time.monotonic() + limit
        while True:
            self._dock_status_event.clear()
            if fresh() and self._expected_dock is None:
                return bool(self.is_docked)
            self._ensure_spun()
            remaining = deadline - time.monotonic()
            if remaining <= 0 or not self._dock_status_event.wait(remaining):
                break
        if fresh():
            return bool(self.is_docked)
        writers = self._dock_status_sub.get_publisher_count()  # 0: the robot was not discovered at all
        message = (
            f"no message on 'dock_status' in namespace '{self.get_namespace()}' after {limit:g} s "
            f"(publishers matched: {writers}) — is the robot (Create 3) or the simulator running?"
        )
        self.error(message)
        raise NavigatorTimeout(message)

    def _on_task_finished(self, slot: TaskSlot) -> None:
        """Nav2's DockRobot/UndockRobot succeeded: a status sent while the robot was still approaching can come in
        after the result, so the next answer must agree with the result (as after the Create 3's Dock/Undock)."""
        if slot.status == GoalStatus.STATUS_SUCCEEDED and slot.task_name in ("dock_robot", "undock_robot"):
            self._expected_dock = slot.task_name == "dock_robot"

    def _dock_action(self, name: str, goal: Any, verb: str) -> bool:
        self.clearLastError()
        status, result = self._tasks.call(name, goal)
        label = verb.capitalize()
        if status is None:
            if name == "undock":
                why = "not docked"
            elif self.is_docked:
                why = "already docked"
            else:
                why = "dock not visible" if self.is_docked is False else "already docked or dock not visible"
            self.setLastError(999, f"{label} goal rejected ({why})")
            self.error(f"{label} goal rejected ({why})")
            return False
        if status == GoalStatus.STATUS_SUCCEEDED and bool(result.is_docked) == (name == "dock"):
            self._expected_dock = bool(result.is_docked)
            self.info(f"{label} succeeded")
            return True
        if self.getTaskError()[1]:  # the server went away meanwhile: the call logged and recorded why
            return False
        self.setLastError(0, f"{label} ended with status {status_name(status)}")
        self.error(f"{label} failed with status {status_name(status)} (is_docked={bool(result.is_docked)})")
        return False

    def dock(self) -> bool:
        """Dock with the Create 3 dock action; blocks until done (upstream returned None).

        Returns:
            True if docked. False if the goal was rejected, failed, or its server went away meanwhile (its node
            left the ROS graph, or it answered nothing for `timeouts.server_lost` s); getTaskError() says which.

        Raises:
            NavigatorTimeout: no dock action server, no answer to the goal, or no result within `timeouts.result`.
        """
        self.info("Docking...")
        return self._dock_action("dock", Dock.Goal(), "dock")

    def undock(self) -> bool:
        """Undock with the Create 3 undock action; blocks until done.

        Returns:
            True if undocked. False if the goal was rejected, failed, or its server went away meanwhile;
            getTaskError() says which.

        Raises:
            NavigatorTimeout: no undock action server, no answer to the goal, or no result within `timeouts.result`.
        """
        self.info("Undocking...")
        return self._dock_action("undock", Undock.Goal(), "undock")

    # --- blocking task helpers ------------------------------------------------------------------------------
    def _runTask(self, started: RunningTask | None, progress: Callable[[Any], str | None]) -> TaskResult:
        if not started:
            code, msg = self.getTaskError()
            self.error(f"Goal was rejected! ({msg or 'no reason given'})")
            return TaskResult.UNKNOWN
        polls = 0
        canceled = False
        while not self.isTaskComplete():
            polls += 1
            feedback = self.getFeedback()
            if feedback is None or polls % 5:
                continue
            line = progress(feedback)
            if line:
                print(line, end="\r", flush=True)
            nav_time = getattr(feedback, "navigation_time", None)
            if not canceled and nav_time is not None and seconds_of(nav_time) > NAVIGATION_TIME_LIMIT:
                canceled = True
                self.cancelTask()
        result = self.getResult()
        if result == TaskResult.SUCCEEDED:
            self.info("Goal succeeded!")
        elif result == TaskResult.CANCELED:
            self.info("Goal was canceled!")
        elif result == TaskResult.FAILED:
            code, msg = self.getTaskError()
            self.info(f"Goal failed! status {self.getTaskStatusName()}, error {code}: {msg}")
        else:
            self.info(f"Goal has an invalid return status! ({self.getTaskStatusName()})")
        return result

    @staticmethod
    def _eta(feedback: Any) -> str | None:
        eta = getattr(feedback, "estimated_time_remaining", None)
        if eta is None:
            return None
        return f"Estimated time of arrival: {seconds_of(eta):.0f} seconds.{'':<12}"

    def startToPose(self, pose: PoseStamped) -> TaskResult:
        """goToPose and wait, printing the ETA; cancels after 600 s of navigation.

        Args:
            pose: the goal, in the map frame.

        Returns:
            The TaskResult: FAILED also when the server went away during the goal (see isTaskComplete), UNKNOWN
            when the goal was rejected.

        Raises:
            NavigatorTimeout: no navigate_to_pose server, or no answer to the goal.
            KeyboardInterrupt, SystemExit: SIGINT or SIGTERM came (the goal's cancel was sent; see BasicNavigator).
        """
        check_pose_stamped(pose, "pose")
        return self._runTask(self.goToPose(pose), self._eta)

    def startThroughPoses(self, poses: list[PoseStamped]) -> TaskResult:
        """goThroughPoses and wait, printing the ETA.

        Args:
            poses: the poses to pass through, in order.

        Returns:
            The TaskResult, as startToPose's.
        """
        return self._runTask(self.goThroughPoses(poses), self._eta)

    def startFollowWaypoints(self, poses: list[PoseStamped]) -> TaskResult:
        """followWaypoints and wait, printing the current waypoint.

        Args:
            poses: the waypoints, in order.

        Returns:
            The TaskResult, as startToPose's.
        """
        total = len(poses)
        started = self.followWaypoints(poses)

        def progress(feedback: Any) -> str:
            return f"Executing current waypoint: {feedback.current_waypoint + 1}/{total:<5}"

        return self._runTask(started, progress)


def _enter_pressed() -> Callable[[], bool]:
    """A non-blocking check for a line (Enter) or end of input on stdin."""
    stream = sys.stdin
    state = {"done": stream is None}
    try:
        fd = stream.fileno() if stream is not None else -1
    except (AttributeError, OSError, ValueError):
        fd = -1
    if fd >= 0:

        def check() -> bool:
            if not state["done"]:
                ready, _, _ = select.select([stream], [], [], 0)
                if ready:
                    stream.readline()  # a line (Enter) or '' at end of input: either ends the path
                    state["done"] = True
            return state["done"]

        return check

    # No file descriptor (e.g. a StringIO in tests): read in a thread.
    event = threading.Event()

    def reader() -> None:
        try:
            stream.readline()
        finally:
            event.set()

    if stream is not None:
        threading.Thread(target=reader, daemon=True).start()
    else:
        event.set()
    return event.is_set
