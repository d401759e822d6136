"""The viewer's ROS side: a node per viewed namespace that fills a ViewerState and carries out the page's tools.

All rclpy calls run in one thread (`ViewerBridge`'s spin thread); the web server hands it work with `submit`.
Subscriptions keep depth 1 and the thread drains them at a bounded pace, so however fast the simulator runs the
viewer handles a bounded number of messages per second and never queues old ones: it only wants the newest.
The goal/feedback/status of navigation tasks started by anyone (the user's script too) come from the actions'
hidden status and feedback topics; the Cancel tool cancels every navigation goal (CancelGoal with a zero id).
"""

from __future__ import annotations

import math
import os
import queue
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

import numpy as np
import rclpy
from action_msgs.msg import GoalStatusArray
from action_msgs.srv import CancelGoal
from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.msg import DockStatus
from nav2_msgs.action import FollowWaypoints, NavigateThroughPoses, NavigateToPose
from nav2_msgs.msg import ParticleCloud
from nav_msgs.msg import Goals, OccupancyGrid, Odometry, Path
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, LaserScan
from tf2_msgs.msg import TFMessage

from tb4.core.units import seconds_of
from tb4.ros.convert import pose_to_tuple, quaternion_to_yaw, time_msg, yaw_to_quaternion
from tb4.viewer.create3_panel import Create3Panel
from tb4.viewer.protocol import CancelCommand, Command, PoseCommand, PressCommand
from tb4.viewer.state import Grid, ViewerState

__all__ = ["ViewerBridge", "RobotBridge", "world_info", "match_world", "INITIAL_POSE_COVARIANCE", "DRAIN_PERIOD"]

T = TypeVar("T")

DRAIN_PERIOD = 0.04  # s between two drains of the subscriptions: at most 25 messages per topic and second
NAMESPACE_SCAN_PERIOD = 2.0  # s between two looks at the graph for robot namespaces
#: What RViz's "2D Pose Estimate" sends: 0.5 m standard deviation in x and y, ~15 degrees in yaw.
INITIAL_POSE_COVARIANCE = [0.0] * 36
INITIAL_POSE_COVARIANCE[0] = INITIAL_POSE_COVARIANCE[7] = 0.25
INITIAL_POSE_COVARIANCE[35] = 0.06853891945200942

LATEST = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
SENSOR = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT)
#: Actions whose status the page shows as "the current task"; the first three also give feedback.
FEEDBACK_ACTIONS: dict[str, Any] = {
    "navigate_to_pose": NavigateToPose,
    "navigate_through_poses": NavigateThroughPoses,
    "follow_waypoints": FollowWaypoints,
}
STATUS_ONLY_ACTIONS = ("dock", "undock", "dock_robot", "undock_robot", "spin", "backup", "drive_on_heading", "wait")
CANCEL_ACTIONS = tuple(FEEDBACK_ACTIONS)
GOAL_STATUS = {1: "accepted", 2: "executing", 3: "canceling", 4: "succeeded", 5: "canceled", 6: "aborted"}


def _uuid(goal_id: Any) -> str:
    return bytes(goal_id.uuid).hex()


def world_info(world: Any) -> dict[str, Any]:
    """The page's view of a tb4 world: its name, the dock, the named destinations and the route graph."""
    return {
        "name": world.name,
        "dock": {"x": world.dock[0], "y": world.dock[1], "yaw": world.dock[2]},
        "destinations": [
            {"name": d.name, "x": d.x, "y": d.y, "yaw": d.yaw, "description": d.description}
            for d in world.destinations.values()
        ],
        "route_graph": _route_graph_info(getattr(world, "route_graph", None)),
    }


def _route_graph_info(path: Any) -> dict[str, Any] | None:
    """Nodes [id, x, y] and undirected edges [x0, y0, x1, y1] of a route graph file (None without one)."""
    if path is None:
        return None
    from tb4.config import ConfigError
    from tb4.nav.route_graph import load_route_graph

    try:
        graph = load_route_graph(path)
    except ConfigError:  # a broken graph must not break the viewer
        return None
    return {
        "nodes": [[n.id, n.x, n.y] for n in graph.nodes.values()],
        "edges": [list(seg) for seg in graph.segments()],
    }


_WORLD_CACHE: dict[str, tuple[tuple[int, int, float, float, float], dict[str, Any]]] = {}


def match_world(grid: Grid) -> dict[str, Any] | None:
    """The shipped world whose map has this grid's size, resolution and origin (None if none does)."""
    from tb4.sim.world import available_worlds, load_world

    for name in available_worlds():
        if name not in _WORLD_CACHE:
            try:
                world = load_world(name)
            except Exception:  # a broken world file must not break the viewer
                continue
            m = world.map
            signature = Grid(m.data, m.resolution, m.origin_x, m.origin_y).signature()
            _WORLD_CACHE[name] = (signature, world_info(world))
        signature, info = _WORLD_CACHE[name]
        if signature == grid.signature():
            return info
    return None


def _grid(msg: OccupancyGrid) -> Grid:
    info = msg.info
    data = np.frombuffer(msg.data, dtype=np.int8) if len(msg.data) else np.zeros(0, dtype=np.int8)
    if info.width == 0 or info.height == 0 or data.size != info.width * info.height:
        raise ValueError(f"grid of {data.size} cells does not match {info.width} x {info.height}")
    origin = info.origin
    return Grid(
        data=data.reshape(info.height, info.width).copy(),
        resolution=float(info.resolution),
        origin_x=float(origin.position.x),
        origin_y=float(origin.position.y),
        frame=msg.header.frame_id or "map",
        origin_yaw=quaternion_to_yaw(origin.orientation),
    )


class RobotBridge:
    """Subscriptions, publisher and action clients of one robot namespace, feeding one ViewerState."""

    def __init__(self, context: Any, namespace: str, state: ViewerState, world: dict[str, Any] | None = None):
        self.namespace = namespace
        self.state = state
        self.fixed_world = world
        self.callbacks = 0
        self.node = Node(f"tb4_viewer_{os.getpid()}", namespace=namespace or "/", context=context)
        self._logger = self.node.get_logger()
        self._world_signature: tuple | None = None
        sub = self._subscribe
        sub(OccupancyGrid, "map", self._on_map, LATCHED)
        sub(OccupancyGrid, "global_costmap/costmap", lambda m: self._on_costmap("global_costmap", m), LATCHED)
        sub(OccupancyGrid, "local_costmap/costmap", lambda m: self._on_costmap("local_costmap", m), LATEST)
        sub(LaserScan, "scan", self._on_scan, SENSOR)
        sub(Odometry, "odom", self._on_odom, SENSOR)
        sub(TFMessage, "tf", self._on_tf, QoSProfile(depth=4, reliability=ReliabilityPolicy.RELIABLE))
        sub(PoseWithCovarianceStamped, "amcl_pose", self._on_amcl, LATCHED)
        sub(ParticleCloud, "particle_cloud", self._on_particles, SENSOR)
        sub(Path, "plan", self._on_plan, LATEST)
        sub(Goals, "goals", self._on_goals, QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE))
        sub(BatteryState, "battery_state", self._on_battery, SENSOR)
        sub(DockStatus, "dock_status", self._on_dock, SENSOR)
        sub(Clock, "/clock", self._on_clock, LATEST)
        status_qos = QoSProfile(
            depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
        )
        for action in (*FEEDBACK_ACTIONS, *STATUS_ONLY_ACTIONS):
            sub(GoalStatusArray, f"{action}/_action/status", self._status_handler(action), status_qos)
        for action, action_type in FEEDBACK_ACTIONS.items():
            sub(action_type.Impl.FeedbackMessage, f"{action}/_action/feedback", self._feedback_handler(action), LATEST)
        self.initial_pose_pub = self.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        self.nav_client: Any = ActionClient(self.node, NavigateToPose, "navigate_to_pose")
        self.cancel_clients: dict[str, Any] = {
            a: self.node.create_client(CancelGoal, f"{a}/_action/cancel_goal") for a in CANCEL_ACTIONS
        }
        self.create3 = Create3Panel(self.node, state, self._subscribe)
        if world is not None:
            state.set_world(world)

    def _subscribe(self, msg_type: Any, topic: str, callback: Callable[[Any], None], qos: QoSProfile) -> None:
        def guarded(msg: Any) -> None:
            self.callbacks += 1
            try:
                callback(msg)
            except Exception as exc:  # a malformed message must not stop the viewer
                self._logger.warn(f"ignored a message on {topic}: {type(exc).__name__}: {exc}", throttle_duration_sec=5)

        self.node.create_subscription(msg_type, topic, guarded, qos)

    def destroy(self) -> None:
        self.nav_client.destroy()
        self.node.destroy_node()

    # --- topics -> state ---------------------------------------------------------------------------------------
    def _on_map(self, msg: OccupancyGrid) -> None:
        grid = _grid(msg)
        self.state.set_layer("map", grid)
        if self.fixed_world is None and grid.signature() != self._world_signature:
            self._world_signature = grid.signature()
            # Loading the shipped worlds' maps takes a moment: do not hold up the spin thread.
            threading.Thread(target=lambda: self.state.set_world(match_world(grid)), daemon=True).start()

    def _on_costmap(self, name: str, msg: OccupancyGrid) -> None:
        self.state.set_layer(name, _grid(msg))

    def _on_scan(self, msg: LaserScan) -> None:
        ranges = np.frombuffer(msg.ranges, dtype=np.float32) if len(msg.ranges) else np.zeros(0, np.float32)
        self.state.set_scan(ranges.copy(), msg.angle_min, msg.angle_increment, msg.range_min, msg.range_max)

    def _on_odom(self, msg: Odometry) -> None:
        self.state.set_velocity(msg.twist.twist.linear.x, msg.twist.twist.angular.z)

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

    def _on_amcl(self, msg: PoseWithCovarianceStamped) -> None:
        p = msg.pose.pose
        self.state.set_amcl((float(p.position.x), float(p.position.y), quaternion_to_yaw(p.orientation)))

    def _on_particles(self, msg: ParticleCloud) -> None:
        pts = np.array([(p.pose.position.x, p.pose.position.y) for p in msg.particles], dtype=np.float64)
        self.state.set_particles(pts.reshape(-1, 2))

    def _on_plan(self, msg: Path) -> None:
        points = np.array(
            [pose_to_tuple(p) for p in msg.poses],
            dtype=np.float64,
        ).reshape(-1, 3)
        self.state.set_plan(points[np.isfinite(points).all(axis=1)], msg.header.frame_id)

    def _on_goals(self, msg: Goals) -> None:
        self.state.set_goals([pose_to_tuple(p) for p in msg.goals])

    def _on_battery(self, msg: BatteryState) -> None:
        charging = {
            BatteryState.POWER_SUPPLY_STATUS_CHARGING: "charging",
            BatteryState.POWER_SUPPLY_STATUS_DISCHARGING: "discharging",
            BatteryState.POWER_SUPPLY_STATUS_FULL: "full",
            BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING: "not charging",
        }.get(msg.power_supply_status, "unknown")
        pct = float(msg.percentage)
        self.state.set_battery(
            {
                "percentage": round(pct, 4) if math.isfinite(pct) else None,
                "status": charging,
                "voltage": round(float(msg.voltage), 2) if math.isfinite(msg.voltage) else None,
            }
        )

    def _on_dock(self, msg: DockStatus) -> None:
        self.state.set_dock(msg.is_docked, msg.dock_visible)

    def _on_clock(self, msg: Clock) -> None:
        self.state.set_sim_time(seconds_of(msg.clock))

    def _status_handler(self, action: str) -> Callable[[GoalStatusArray], None]:
        def handler(msg: GoalStatusArray) -> None:
            pairs = [(_uuid(s.goal_info.goal_id), int(s.status)) for s in msg.status_list]
            for goal_id, status in self.state.tasks.on_status(action, pairs):
                if status in (4, 5, 6):
                    level = "info" if status == 4 else "warn"
                    self.state.notice(level, f"{action} {GOAL_STATUS[status]} (goal {goal_id[:8]})")

        return handler

    def _feedback_handler(self, action: str) -> Callable[[Any], None]:
        def handler(msg: Any) -> None:
            fb = msg.feedback
            values: dict[str, Any] = {}
            if action == "follow_waypoints":
                values["current_waypoint"] = int(fb.current_waypoint)
            else:
                values["distance_remaining"] = round(float(fb.distance_remaining), 2)
                values["eta"] = round(seconds_of(fb.estimated_time_remaining), 1)
                values["navigation_time"] = round(seconds_of(fb.navigation_time), 1)
                values["recoveries"] = int(fb.number_of_recoveries)
            if action == "navigate_through_poses":
                values["poses_remaining"] = int(fb.number_of_poses_remaining)
                waypoints = []
                for w in getattr(fb, "waypoint_statuses", ()):  # Kilted's feedback only
                    p = w.waypoint_pose.pose
                    waypoints.append(
                        {
                            "x": round(float(p.position.x), 3),
                            "y": round(float(p.position.y), 3),
                            "yaw": round(quaternion_to_yaw(p.orientation), 3),
                            "status": int(w.waypoint_status),
                        }
                    )
                self.state.set_waypoint_statuses(waypoints)
            self.state.tasks.on_feedback(action, _uuid(msg.goal_id), values)

        return handler

    # --- the page's tools (spin thread) --------------------------------------------------------------------
    def publish_initial_pose(self, x: float, y: float, yaw: float) -> str:
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        stamp = self.state.sim_time or 0.0
        msg.header.stamp = time_msg(stamp)
        msg.pose.pose.position.x = float(x)
        msg.pose.pose.position.y = float(y)
        msg.pose.pose.orientation = yaw_to_quaternion(yaw)
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
        goal = NavigateToPose.Goal()
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x = float(x)
        goal.pose.pose.position.y = float(y)
        goal.pose.pose.orientation = yaw_to_quaternion(yaw)
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
        status = GOAL_STATUS.get(response.status, str(response.status))
        error = getattr(response.result, "error_msg", "")
        level = "info" if response.status == 4 else "warn"
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


class ViewerBridge:
    """One rclpy context and spin thread for the viewer; RobotBridges are created per namespace on demand."""

    def __init__(
        self, default_namespace: str = "", world: dict[str, Any] | None = None, robot_radius: float | None = None
    ):
        self.default_namespace = default_namespace
        self.world = world
        self.robot_radius = robot_radius
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.executor = SingleThreadedExecutor(context=self.context)
        self._ops: queue.SimpleQueue[tuple[Callable[[], Any], Future]] = queue.SimpleQueue()
        self._robots: dict[str, RobotBridge] = {}
        self._users: dict[str, int] = {}
        self._namespaces: list[str] = [default_namespace]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="tb4-viewer-ros", daemon=True)
        self._thread.start()
        try:
            self.acquire(default_namespace, timeout=20.0)  # the default namespace stays subscribed (warm state)
        except BaseException:
            self.close()
            raise

    # --- called from any thread ---------------------------------------------------------------------------
    def submit(self, fn: Callable[[], T]) -> Future:
        """Run `fn` in the spin thread (where every rclpy call happens); the future carries its result."""
        future: Future = Future()
        if self._stop.is_set():
            future.set_exception(RuntimeError("the viewer's ROS bridge is stopped"))
        else:
            self._ops.put((fn, future))
        return future

    def acquire(self, namespace: str, timeout: float = 10.0) -> ViewerState:
        """Start (or share) the bridge of a namespace; pair with release()."""

        def op() -> ViewerState:
            robot = self._robots.get(namespace)
            if robot is None:
                state = ViewerState(namespace, robot_radius=self.robot_radius)
                world = self.world if namespace == self.default_namespace else None
                robot = RobotBridge(self.context, namespace, state, world)
                self._robots[namespace] = robot
                self.executor.add_node(robot.node)
            self._users[namespace] = self._users.get(namespace, 0) + 1
            return robot.state

        return self.submit(op).result(timeout=timeout)

    def release(self, namespace: str) -> None:
        """A page stopped viewing `namespace`: drop its node when nobody else does (never the default one)."""

        def op() -> None:
            users = self._users.get(namespace, 0) - 1
            self._users[namespace] = max(0, users)
            if users <= 0 and namespace != self.default_namespace and namespace in self._robots:
                robot = self._robots.pop(namespace)
                self.executor.remove_node(robot.node)
                robot.destroy()

        self.submit(op)

    def robot(self, namespace: str) -> RobotBridge:
        """The bridge of a namespace (only from the spin thread, i.e. inside a submitted function)."""
        robot = self._robots.get(namespace)
        if robot is None:
            raise RuntimeError(f"namespace '{namespace or '/'}' is not being viewed")
        return robot

    def namespaces(self) -> list[str]:
        return list(self._namespaces)

    def command(self, namespace: str, command: Command, timeout: float = 10.0) -> str:
        """Carry out a page's tool command in `namespace`; returns what was done, raises RuntimeError if it can't."""

        def op() -> str:
            robot = self.robot(namespace)
            if isinstance(command, PoseCommand) and command.kind == "initial_pose":
                return robot.publish_initial_pose(command.x, command.y, command.yaw)
            if isinstance(command, PoseCommand) and command.kind == "goal":
                return robot.send_goal(command.x, command.y, command.yaw)
            if isinstance(command, CancelCommand):
                return robot.cancel_all()
            if isinstance(command, PressCommand):
                return robot.create3.press(command.button)
            raise ValueError(f"not a ROS command: {command!r}")

        return self.submit(op).result(timeout=timeout)

    def close(self, timeout: float = 5.0) -> None:
        self._stop.set()
        self._thread.join(timeout=timeout)

    # --- the spin thread ------------------------------------------------------------------------------------
    def _run_ops(self) -> None:
        while True:
            try:
                fn, future = self._ops.get_nowait()
            except queue.Empty:
                return
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(fn())
            except BaseException as exc:
                future.set_exception(exc)

    def _drain(self) -> None:
        """Take what is ready now (each subscription holds at most its newest message), then return."""
        for _ in range(64):
            before = sum(r.callbacks for r in self._robots.values())
            self.executor.spin_once(timeout_sec=0.0)
            if sum(r.callbacks for r in self._robots.values()) == before:
                return

    def _scan_namespaces(self) -> None:
        robot = self._robots.get(self.default_namespace)
        if robot is None:
            return
        found = {self.default_namespace, *self._robots}
        for name, types in robot.node.get_topic_names_and_types():
            if name.endswith("/odom") and "nav_msgs/msg/Odometry" in types:
                found.add(name[: -len("/odom")])
        self._namespaces = sorted(found)

    @property
    def alive(self) -> bool:
        """Whether the spin thread still runs (the page's data is live)."""
        return self._thread.is_alive()

    def _spin(self) -> None:
        next_scan = 0.0
        last_error = -math.inf
        try:
            while not self._stop.is_set() and self.context.ok():
                start = time.monotonic()
                try:
                    self._run_ops()
                    self._drain()
                    if start >= next_scan:
                        next_scan = start + NAMESPACE_SCAN_PERIOD
                        self._scan_namespaces()
                except Exception as exc:  # one bad callback must not end the viewer's ROS side
                    if start - last_error > 5.0:
                        last_error = start
                        print(f"tb4 view: ROS callback failed: {type(exc).__name__}: {exc}", file=sys.stderr)
                time.sleep(max(0.0, DRAIN_PERIOD - (time.monotonic() - start)))
        finally:
            self._shutdown()

    def _shutdown(self) -> None:
        for robot in list(self._robots.values()):
            self.executor.remove_node(robot.node)
            robot.destroy()
        self._robots.clear()
        self.executor.shutdown(timeout_sec=1.0)
        rclpy.try_shutdown(context=self.context)
        while True:  # nobody will run what is still queued
            try:
                _, future = self._ops.get_nowait()
            except queue.Empty:
                break
            if future.set_running_or_notify_cancel():
                future.set_exception(RuntimeError("the viewer's ROS bridge stopped"))
