"""Watches a run over ROS like a user's tools would: action feedback/status, battery, dock status, sim clock.

It feeds the progress display and the --json events; it never commands the robot.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from tb4.core.units import seconds_of
from tb4.core.waits import wait_until

__all__ = ["RunState", "RunMonitor", "WATCHED_ACTIONS", "truth_pose"]


def truth_pose(data: bytes) -> tuple[float, float, float]:
    """(x, y, yaw) of a serialized ground_truth Odometry; NaNs when the bytes do not decode (a hostile or broken
    publisher), which the localization error never pairs."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message

    from tb4.ros.convert import pose_to_tuple

    try:
        return pose_to_tuple(deserialize_message(data, Odometry).pose.pose)
    except RuntimeError:  # rclpy's RMWError: "failed to deserialize ROS message"
        return (math.nan, math.nan, math.nan)


#: Actions whose progress we show, with their package.
WATCHED_ACTIONS = {
    "navigate_to_pose": ("nav2_msgs", "NavigateToPose"),
    "navigate_through_poses": ("nav2_msgs", "NavigateThroughPoses"),
    "follow_waypoints": ("nav2_msgs", "FollowWaypoints"),
    "dock": ("irobot_create_msgs", "Dock"),
    "undock": ("irobot_create_msgs", "Undock"),
}


@dataclass
class RunState:
    """The latest known state of the run (read by the display thread under `lock`)."""

    task: str = "starting"
    distance_remaining: float | None = None
    eta_sim: float | None = None
    navigation_time: float | None = None
    recoveries: int = 0
    waypoint: int | None = None
    poses_remaining: int | None = None
    battery: float | None = None
    charging: bool = False
    docked: bool | None = None
    dock_visible: bool | None = None
    sim_time: float = 0.0
    real_time_factor: float | None = None
    localization_error: float | None = None  # m, amcl_pose against ground_truth (when the simulator has it)
    heading_error_deg: float | None = None
    bumps: int = 0  # bumper presses seen on hazard_detection (each contact once)
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def snapshot(self) -> dict[str, Any]:
        with self.lock:
            return self.snapshot_locked()

    def snapshot_locked(self) -> dict[str, Any]:
        """snapshot() for a caller already holding `lock`."""
        return {k: v for k, v in self.__dict__.items() if k != "lock"}


class RunMonitor:
    """A node in its own rclpy context, spinning in a background thread."""

    def __init__(self, namespace: str = "") -> None:
        import importlib

        from action_msgs.msg import GoalStatusArray
        from irobot_create_msgs.msg import DockStatus
        from rclpy.qos import qos_profile_sensor_data
        from rosgraph_msgs.msg import Clock
        from sensor_msgs.msg import BatteryState

        from tb4.ros.background import BackgroundNode
        from tb4.ros.qos import ACTION_STATUS

        self.state = RunState()
        self.events: list[dict[str, Any]] = []
        self._task_starts: list[dict[str, Any]] = []  # the state as each task began (see pop_task_starts)
        self._events_lock = threading.Lock()
        # thousands of messages per wall second at --rate max: dispatched from C++, not a Python wait set
        self._background = BackgroundNode("tb4_run_monitor", namespace, events_executor=True)
        n = self.node = self._background.node
        # each watched action's feedback and status, and hazard_detection: volatile news (wait_for_publishers)
        self._news_subscriptions: list[Any] = []
        for action, (package, name) in WATCHED_ACTIONS.items():
            action_type = getattr(importlib.import_module(f"{package}.action"), name)
            self._news_subscriptions.append(
                n.create_subscription(
                    action_type.Impl.FeedbackMessage,
                    f"{action}/_action/feedback",
                    lambda msg, a=action: self._on_feedback(a, msg.feedback),
                    10,
                )
            )
            self._news_subscriptions.append(
                n.create_subscription(
                    GoalStatusArray,
                    f"{action}/_action/status",
                    lambda msg, a=action: self._on_status(a, msg),
                    ACTION_STATUS,
                )
            )
        n.create_subscription(BatteryState, "battery_state", self._on_battery, qos_profile_sensor_data)
        n.create_subscription(DockStatus, "dock_status", self._on_dock, qos_profile_sensor_data)
        n.create_subscription(Clock, "/clock", self._on_clock, 10)
        from irobot_create_msgs.msg import HazardDetection, HazardDetectionVector

        self._bump_type = HazardDetection.BUMP
        self._pressed = False
        # sent on every change of the hazards (bounded in wall rate otherwise): a press is never missed
        self._news_subscriptions.append(
            n.create_subscription(HazardDetectionVector, "hazard_detection", self._on_hazards, 10)
        )
        from geometry_msgs.msg import PoseWithCovarianceStamped
        from nav_msgs.msg import Odometry
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from tb4.ros.convert import pose_to_tuple, serialized_header_stamp
        from tb4.runner.localization_error import LocalizationErrorTracker

        self._loc = LocalizationErrorTracker()
        self._loc_lock = threading.Lock()
        latched = QoSProfile(
            depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
        )

        def stamp(msg: Any) -> float:
            return seconds_of(msg.header.stamp)

        def on_truth(data: bytes) -> None:
            """ground_truth comes raw: its stamp is read at once, the pose only if an amcl_pose pairs with it."""
            try:
                t = serialized_header_stamp(data)
            except ValueError:  # too short to hold a stamp (bytes anyone on the domain can publish): ignored
                return
            with self._loc_lock:
                err = self._loc.add_truth_later(t, lambda: truth_pose(data))  # an estimate waiting for it, paired
                heading = self._loc.heading_error_deg
            if err is not None:
                self._show_localization_error(err, heading)

        def on_estimate(msg: Any) -> None:
            with self._loc_lock:
                err = self._loc.add_estimate(stamp(msg), *pose_to_tuple(msg.pose.pose))
                heading = self._loc.heading_error_deg
            if err is not None:
                self._show_localization_error(err, heading)

        n.create_subscription(Odometry, "ground_truth", on_truth, qos_profile_sensor_data, raw=True)
        n.create_subscription(PoseWithCovarianceStamped, "amcl_pose", on_estimate, latched)
        self._clock_window: tuple[float, float] | None = None
        self._reported: set[tuple[str, bytes]] = set()  # (action, goal id) whose result is reported
        self._running: set[tuple[str, bytes]] = set()  # (action, goal id) seen accepted or executing
        self._goals_since = -math.inf  # goals accepted earlier (stamp in the server's time) are not this run's
        self._background.start()

    def close(self) -> None:
        self._background.close()

    def wait_for_publishers(self, timeout: float) -> bool:
        """Wait (at most `timeout` wall s) until each watched action's feedback and status publishers, and the
        hazard_detection publisher, are matched.

        All are volatile: what the simulator publishes before it has matched this monitor never reaches it, and at
        --rate max a whole goal takes a few wall milliseconds, and bump_and_go's bumps come within a wall second of
        its start. On a loaded machine the simulator's few hundred endpoints can take seconds to match (runs whose
        navigate_to_pose, or every bump, went unreported under load). The runner waits here before the tutorial may
        send anything, while the simulator holds its time; False if some never matched."""
        return wait_until(
            lambda: all(sub.get_publisher_count() > 0 for sub in self._news_subscriptions), timeout, period=0.01
        )

    def mission_starts(self, attached: bool) -> None:
        """The mission is about to start. A simulator of the run's own has had no goal yet; one the run attached
        to may have finished goals whose latched status still lists them: those are left unreported.

        Args:
            attached: the run attached to a simulator or robot that was already up (tb4 run --attach).
        """
        if not attached:
            return
        with self.state.lock:  # the server stamps goals in its time: the simulator's clock, or a robot's wall time
            self._goals_since = self.state.sim_time if self._clock_window is not None else time.time()

    def pop_events(self) -> list[dict[str, Any]]:
        with self._events_lock:
            events, self.events = self.events, []
        return events

    def pop_task_starts(self) -> list[dict[str, Any]]:
        """The state as each task began, since the last call. The display samples the state a few times a wall
        second, and at --rate max a whole task (a 20 m drive) can start and end between two samples: without
        these, its progress would never be shown or reported."""
        with self._events_lock:
            starts, self._task_starts = self._task_starts, []
        return starts

    def _task_began_locked(self) -> None:
        """Keep the state as a task begins (the caller holds the state's lock)."""
        start = self.state.snapshot_locked()
        with self._events_lock:
            self._task_starts.append(start)

    def _show_localization_error(self, position: float, heading_deg: float | None) -> None:
        with self.state.lock:
            self.state.localization_error = position
            self.state.heading_error_deg = heading_deg

    def _event(self, **fields: Any) -> None:
        with self._events_lock:
            self.events.append(fields)

    # --- callbacks --------------------------------------------------------------------------------------------
    def _on_feedback(self, action: str, fb: Any) -> None:
        s = self.state
        with s.lock:
            began = s.task != action
            s.task = action
            if hasattr(fb, "distance_remaining"):
                s.distance_remaining = float(fb.distance_remaining)
                s.eta_sim = seconds_of(fb.estimated_time_remaining)
                s.navigation_time = seconds_of(fb.navigation_time)
                s.recoveries = int(fb.number_of_recoveries)
            if hasattr(fb, "number_of_poses_remaining"):
                s.poses_remaining = int(fb.number_of_poses_remaining)
            if hasattr(fb, "current_waypoint"):
                s.waypoint = int(fb.current_waypoint)
            if began:
                self._task_began_locked()

    def _on_status(self, action: str, msg: Any) -> None:
        goals = [((action, bytes(st.goal_info.goal_id.uuid)), st) for st in msg.status_list]
        executing = [key for key, st in goals if st.status in (1, 2)]  # accepted, executing
        finished = [(key, st) for key, st in goals if st.status in (4, 5, 6)]
        new = [
            (key, st)
            for key, st in finished
            if key not in self._reported and seconds_of(st.goal_info.stamp) >= self._goals_since
        ]
        with self.state.lock:
            self._running.update(executing)
            if executing:
                if self.state.task != action:
                    self._begin_task_locked(action)
            elif finished:
                # a goal known only by its end (the simulator matched this monitor late: the status comes latched)
                # began too, between two looks
                if any(key not in self._running for key, _ in new):
                    self._begin_task_locked(action)
                if self.state.task == action:
                    self.state.task = f"{action} ({_STATUS[finished[-1][1].status]})"
        for key, st in new:
            self._reported.add(key)
            self._event(event="result", action=action, status=_STATUS[st.status])

    def _begin_task_locked(self, action: str) -> None:
        """`action` is the task now: its earlier task's progress is cleared, and the start kept (caller holds the
        state's lock)."""
        self.state.distance_remaining = self.state.eta_sim = None
        self.state.waypoint = self.state.poses_remaining = None
        self.state.task = action
        self._task_began_locked()

    def _on_battery(self, msg: Any) -> None:
        with self.state.lock:
            self.state.battery = float(msg.percentage)
            self.state.charging = msg.power_supply_status == 1

    def _on_hazards(self, msg: Any) -> None:
        pressed = any(d.type == self._bump_type for d in msg.detections)
        if pressed and not self._pressed:
            with self.state.lock:
                self.state.bumps += 1
                count, t = self.state.bumps, self.state.sim_time
            self._event(event="bump", count=count, sim_time=round(t, 2))
        self._pressed = pressed

    def _on_dock(self, msg: Any) -> None:
        with self.state.lock:
            self.state.docked = bool(msg.is_docked)
            self.state.dock_visible = bool(msg.dock_visible)

    def _on_clock(self, msg: Any) -> None:
        sim = seconds_of(msg.clock)
        wall = time.monotonic()
        with self.state.lock:
            self.state.sim_time = sim
            if self._clock_window is None:
                self._clock_window = (wall, sim)
            elif wall - self._clock_window[0] >= 1.0:
                w0, s0 = self._clock_window
                self.state.real_time_factor = (sim - s0) / (wall - w0)
                self._clock_window = (wall, sim)


_STATUS = {4: "succeeded", 5: "canceled", 6: "aborted"}
