"""One viewed robot namespace: the subscriptions that fill its ViewerState, and the page's tools carried out
there (2D Pose Estimate, Nav2 Goal, Cancel, the Create 3's buttons). Everything runs in the viewer's spin thread.

Subscriptions keep depth 1: the viewer only wants the newest message of each topic. The goal/feedback/status of
navigation tasks started by anyone (the user's script too) come from the actions' hidden status and feedback
topics; the Cancel tool cancels every navigation goal (CancelGoal with a zero id).
"""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
from action_msgs.msg import GoalStatusArray
from action_msgs.srv import CancelGoal
from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.msg import DockStatus
from nav2_msgs.action import FollowWaypoints, NavigateThroughPoses, NavigateToPose
from nav2_msgs.msg import ParticleCloud
from nav_msgs.msg import Goals, OccupancyGrid, Odometry, Path
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, LaserScan
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from tb4.processes import abandoned_ports_watched
from tb4.ros.action_client import ActionClient
from tb4.ros.background import destroy_node_and_actions
from tb4.ros.convert import duration_to_seconds, pose_stamped, quaternion_to_yaw, time_msg
from tb4.ros.qos import LATCHED, LATEST, REQUESTS, SENSOR
from tb4.ros.world_topic import FLEET_TOPIC, WORLD_TOPIC, parse_fleet
from tb4.viewer.create3_panel import Create3Panel
from tb4.viewer.messages import (
    battery_values,
    feedback_values,
    goal_uuid,
    grid_from_msg,
    pose_of,
    waypoint_statuses,
)
from tb4.viewer.state import ViewerState
from tb4.viewer.tracking import STATUS_NAMES
from tb4.viewer.world_info import WorldInfoCache

__all__ = ["RobotBridge", "INITIAL_POSE_COVARIANCE", "FEEDBACK_ACTIONS", "STATUS_ONLY_ACTIONS"]

#: What RViz's "2D Pose Estimate" sends: 0.5 m standard deviation in x and y, ~15 degrees in yaw.
INITIAL_POSE_COVARIANCE = [0.0] * 36
INITIAL_POSE_COVARIANCE[0] = INITIAL_POSE_COVARIANCE[7] = 0.25
INITIAL_POSE_COVARIANCE[35] = 0.06853891945200942

#: Actions whose status the page shows as "the current task"; these three also give feedback.
FEEDBACK_ACTIONS: dict[str, Any] = {
    "navigate_to_pose": NavigateToPose,
    "navigate_through_poses": NavigateThroughPoses,
    "follow_waypoints": FollowWaypoints,
}
STATUS_ONLY_ACTIONS = ("dock", "undock", "dock_robot", "undock_robot", "spin", "backup", "drive_on_heading", "wait")
CANCEL_ACTIONS = tuple(FEEDBACK_ACTIONS)
SUCCEEDED, ENDED = 4, (4, 5, 6)


class RobotBridge:
    """Subscriptions, publisher and action clients of one robot namespace, feeding one ViewerState.

    Every robot gets the overview subscriptions (where it is, its plan, goals, navigation task and fleet): enough
    to draw a fleet robot the page does not command. `add_details()` adds the rest (map, costmaps, scan, battery,
    the Create 3, every action's status) and the tools, for the robot a page commands; they stay while the
    robot is viewed at all. `world` (from `tb4 view --world`) fixes the world shown; otherwise the simulator's
    `world` topic says it.
    """

    def __init__(
        self,
        context: Any,
        namespace: str,
        state: ViewerState,
        worlds: WorldInfoCache,
        world: dict[str, Any] | None = None,
        detailed: bool = True,
    ):
        self.namespace = namespace
        self.state = state
        self.worlds = worlds
        self.fixed_world = world
        self.callbacks = 0
        self.detailed = False
        self._follows_truth = False
        with abandoned_ports_watched():  # the context's DDS participant may be made with this node
            self.node = Node(f"tb4_viewer_{os.getpid()}", namespace=namespace or "/", context=context)
        self._logger = self.node.get_logger()
        sub = self._subscribe
        sub(TFMessage, "tf", self._on_tf, QoSProfile(depth=4, reliability=ReliabilityPolicy.RELIABLE))
        sub(Path, "plan", self._on_plan, LATEST)
        sub(Goals, "goals", self._on_goals, QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE))
        sub(String, FLEET_TOPIC, self._on_fleet, LATCHED)
        for action in FEEDBACK_ACTIONS:
            sub(GoalStatusArray, f"{action}/_action/status", self._status_handler(action), LATCHED)
        if detailed:
            self.add_details()

    def add_details(self) -> None:
        """Everything the page shows and does for the robot it commands (once; kept while the robot is viewed)."""
        if self.detailed:
            return
        self.detailed = True
        state = self.state
        sub = self._subscribe
        sub(OccupancyGrid, "map", self._layer_handler("map"), LATCHED)
        sub(OccupancyGrid, "global_costmap/costmap", self._layer_handler("global_costmap"), LATCHED)
        sub(OccupancyGrid, "local_costmap/costmap", self._layer_handler("local_costmap"), LATEST)
        sub(String, WORLD_TOPIC, self._on_world, LATCHED)
        sub(LaserScan, "scan", self._on_scan, SENSOR)
        sub(Odometry, "odom", lambda m: state.set_velocity(m.twist.twist.linear.x, m.twist.twist.angular.z), SENSOR)
        sub(PoseWithCovarianceStamped, "amcl_pose", lambda m: state.set_amcl(pose_of(m.pose.pose)), LATCHED)
        sub(ParticleCloud, "particle_cloud", self._on_particles, SENSOR)
        sub(BatteryState, "battery_state", lambda m: state.set_battery(battery_values(m)), SENSOR)
        sub(DockStatus, "dock_status", lambda m: state.set_dock(m.is_docked, m.dock_visible), SENSOR)
        sub(Clock, "/clock", lambda m: state.set_sim_time(duration_to_seconds(m.clock)), LATEST)
        for action in STATUS_ONLY_ACTIONS:
            sub(GoalStatusArray, f"{action}/_action/status", self._status_handler(action), LATCHED)
        for action, action_type in FEEDBACK_ACTIONS.items():
            sub(action_type.Impl.FeedbackMessage, f"{action}/_action/feedback", self._feedback_handler(action), LATEST)
        self.initial_pose_pub = self.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        self.nav_client: Any = ActionClient(self.node, NavigateToPose, "navigate_to_pose")
        self.cancel_clients: dict[str, Any] = {
            a: self.node.create_client(CancelGoal, f"{a}/_action/cancel_goal", qos_profile=REQUESTS)
            for a in CANCEL_ACTIONS
        }
        self.create3 = Create3Panel(self.node, state, self._subscribe)
        if self.fixed_world is not None:
            state.set_world(self.fixed_world)

    def _subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: QoSProfile) -> None:
        def guarded(msg: Any) -> None:
            self.callbacks += 1
            try:
                callback(msg)
            except Exception as exc:  # a malformed message must not stop the viewer
                self._logger.warn(f"ignored a message on {topic}: {type(exc).__name__}: {exc}", throttle_duration_sec=5)

        self.node.create_subscription(msg_type, topic, guarded, qos)

    def destroy(self) -> None:
        destroy_node_and_actions(self.node)

    # --- topics -> state ---------------------------------------------------------------------------------------
    def _layer_handler(self, layer: str) -> Callable[[OccupancyGrid], None]:
        return lambda msg: self.state.set_layer(layer, grid_from_msg(msg))

    def _on_world(self, msg: String) -> None:
        if self.fixed_world is not None:
            return
        reference = msg.data

        def load() -> None:
            info = self.worlds.get(reference)
            if info is None and reference in self.worlds.errors:
                self.state.notice("warn", f"world '{reference}' not shown: {self.worlds.errors[reference]}")
            self.state.set_world(info)

        # Loading a world (its map, its route graph) takes a moment: never in the spin thread.
        threading.Thread(target=load, name="tb4-viewer-world", daemon=True).start()

    def _on_scan(self, msg: LaserScan) -> None:
        ranges = np.frombuffer(msg.ranges, dtype=np.float32) if len(msg.ranges) else np.zeros(0, np.float32)
        self.state.set_scan(ranges.copy(), msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max)

    def _on_tf(self, msg: TFMessage) -> None:
        for t in msg.transforms:
            parent, child = t.header.frame_id.lstrip("/"), t.child_frame_id.lstrip("/")
            r = t.transform.translation
            pose = (float(r.x), float(r.y), quaternion_to_yaw(t.transform.rotation))
            if not all(math.isfinite(v) for v in pose):
                continue
            if child.endswith("base_link") and parent.endswith("odom"):
                self.state.set_odom_base(pose)
            elif child.endswith("odom") and parent.endswith("map"):
                self.state.set_map_odom(pose)

    def _on_particles(self, msg: ParticleCloud) -> None:
        pts = np.array([(p.pose.position.x, p.pose.position.y) for p in msg.particles], dtype=np.float64)
        self.state.set_particles(pts.reshape(-1, 2))

    def _on_fleet(self, msg: String) -> None:
        """Part of a fleet: also follow the simulator's true pose, where the robot is drawn until localized."""
        self.state.set_fleet(parse_fleet(msg.data))
        if self.state.fleet and not self._follows_truth:
            self._follows_truth = True
            self._subscribe(Odometry, "ground_truth", lambda m: self.state.set_truth(pose_of(m.pose.pose)), SENSOR)

    def _on_plan(self, msg: Path) -> None:
        points = np.array([pose_of(p.pose) for p in msg.poses], dtype=np.float64).reshape(-1, 3)
        self.state.set_plan(points[np.isfinite(points).all(axis=1)], msg.header.frame_id)

    def _on_goals(self, msg: Goals) -> None:
        self.state.set_goals([pose_of(p.pose) for p in msg.goals])

    def _status_handler(self, action: str) -> Callable[[GoalStatusArray], None]:
        def handler(msg: GoalStatusArray) -> None:
            pairs = [(goal_uuid(s.goal_info.goal_id), int(s.status)) for s in msg.status_list]
            for goal_id, status in self.state.tasks.on_status(action, pairs):
                if status in ENDED:
                    level = "info" if status == SUCCEEDED else "warn"
                    self.state.notice(level, f"{action} {STATUS_NAMES[status]} (goal {goal_id[:8]})")

        return handler

    def _feedback_handler(self, action: str) -> Callable[[Any], None]:
        def handler(msg: Any) -> None:
            if action == "navigate_through_poses":
                self.state.set_waypoint_statuses(waypoint_statuses(msg.feedback))
            self.state.tasks.on_feedback(action, goal_uuid(msg.goal_id), feedback_values(action, msg.feedback))

        return handler

    # --- the page's tools (spin thread) --------------------------------------------------------------------
    def publish_initial_pose(self, x: float, y: float, yaw: float) -> str:
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = time_msg(self.state.sim_time or 0.0)
        msg.pose.pose = pose_stamped((x, y, yaw)).pose
        msg.pose.covariance = list(INITIAL_POSE_COVARIANCE)
        self.initial_pose_pub.publish(msg)
        text = f"initial pose ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f}°) published on {self._topic('initialpose')}"
        if self.initial_pose_pub.get_subscription_count() == 0:
            text += " — but nothing subscribes to it yet (is the robot or simulator running?)"
            self.state.notice("warn", text)
        else:
            self.state.notice("info", text)
        return text

    def send_goal(self, x: float, y: float, yaw: float) -> str:
        if not self.nav_client.server_is_ready():
            raise RuntimeError(f"no navigate_to_pose server in namespace '{self.namespace or '/'}'")
        goal = NavigateToPose.Goal(pose=pose_stamped((x, y, yaw)))
        self.state.set_goal(x, y, yaw, "page")
        future = self.nav_client.send_goal_async(goal)
        future.add_done_callback(self._on_goal_response)
        return f"goal ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f}°) sent to navigate_to_pose"

    def _on_goal_response(self, future: Any) -> None:
        try:
            handle = future.result()
        except Exception as exc:
            self.state.notice("error", f"sending the goal failed: {exc}")
            return
        if not handle.accepted:
            self.state.notice("warn", "navigate_to_pose rejected the goal (is the navigator active?)")
            return
        handle.get_result_async().add_done_callback(self._on_goal_result)

    def _on_goal_result(self, future: Any) -> None:
        try:
            response = future.result()
        except Exception as exc:
            self.state.notice("error", f"navigate_to_pose result failed: {exc}")
            return
        status = STATUS_NAMES.get(response.status, str(response.status))
        error = getattr(response.result, "error_msg", "")
        level = "info" if response.status == SUCCEEDED else "warn"
        self.state.notice(level, f"navigation goal {status}" + (f": {error}" if error else ""))

    def cancel_all(self) -> str:
        """Cancel every goal of the navigation actions (a CancelGoal request with a zero id and stamp)."""
        ready = [(a, c) for a, c in self.cancel_clients.items() if c.service_is_ready()]
        if not ready:
            raise RuntimeError(f"no navigation action server in namespace '{self.namespace or '/'}'")
        for action, client in ready:
            future = client.call_async(CancelGoal.Request())
            future.add_done_callback(self._cancel_done(action))
        return "cancel requested for every navigation goal"

    def _cancel_done(self, action: str) -> Callable[[Any], None]:
        def done(future: Any) -> None:
            try:
                response = future.result()
            except Exception as exc:
                self.state.notice("error", f"cancel on {action} failed: {exc}")
                return
            if response.goals_canceling:
                self.state.notice("info", f"{action}: canceling {len(response.goals_canceling)} goal(s)")

        return done

    def _topic(self, name: str) -> str:
        return f"{self.namespace}/{name}" if self.namespace else f"/{name}"
