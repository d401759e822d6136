"""The Nav2 side of the simulator: the nodes, actions, services and topics a TurtleBot 4 running Nav2 offers.

Each Nav2 server is a real node with its upstream name (bt_navigator, planner_server, ...) answering
`<node>/get_state`, so scripts (ours or upstream's) find the same graph they find on a robot. The work itself is
done by tb4.nav.NavigationCore in the simulator loop; this module only converts messages.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from geometry_msgs.msg import PoseStamped, Twist
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from nav2_msgs import action as nav2_action
from nav2_msgs.msg import Costmap, CostmapMetaData
from nav2_msgs.srv import (
    ClearCostmapAroundRobot,
    ClearCostmapExceptRegion,
    ClearEntireCostmap,
    GetCostmap,
    IsPathValid,
    LoadMap,
    ManageLifecycleNodes,
)
from nav_msgs.msg import Goals, OccupancyGrid
from nav_msgs.msg import Path as PathMsg
from rclpy.action import ActionClient
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Empty
from std_srvs.srv import Trigger

from tb4.config import ConfigError
from tb4.core.maps import OccupancyMap, load_map
from tb4.nav.planner import PlanError, to_path_code, to_through_poses_code
from tb4.nav.server import NavigationCore, NotLocalizedError
from tb4.ros.amcl import AmclInterfaces
from tb4.ros.bridge import ImmediateTask, TaskActionServer
from tb4.ros.convert import (
    checked_pose,
    costmap_to_occupancy_values,
    duration_to_seconds,
    occupancy_grid_msg,
    path_msg,
    path_to_array,
    pose_msg,
    pose_stamped,
    time_msg,
)
from tb4.ros.docking import DockingServer
from tb4.ros.loop import SimLoop
from tb4.ros.run_record import RunRecord
from tb4.ros.side_tasks import SideTasks
from tb4.wire import get_optional, get_poses, result_code

__all__ = ["Nav2Interfaces", "NAVIGATION_NODES", "LOCALIZATION_NODES"]

NAVIGATION_NODES = (
    "controller_server",
    "smoother_server",
    "planner_server",
    "behavior_server",
    "bt_navigator",
    "waypoint_follower",
    "docking_server",
    "route_server",
)
LOCALIZATION_NODES = ("map_server", "amcl")
PLANNER_IDS = ("", "GridBased")
CONTROLLER_IDS = ("", "FollowPath")
SMOOTHER_IDS = ("", "simple_smoother", "SmoothPath")
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
_STATES = {
    "unconfigured": State.PRIMARY_STATE_UNCONFIGURED,
    "inactive": State.PRIMARY_STATE_INACTIVE,
    "active": State.PRIMARY_STATE_ACTIVE,
    "finalized": State.PRIMARY_STATE_FINALIZED,
}


class Nav2Interfaces:
    """Creates the Nav2 nodes in `namespace` and wires them to the loop's NavigationCore."""

    def __init__(
        self,
        context: Context,
        loop: SimLoop,
        namespace: str = "",
        on_map_change: Callable | None = None,
        record: RunRecord | None = None,
    ):
        self.record = record
        self.loop = loop
        self.nav: NavigationCore = loop.nav
        self.namespace = namespace
        self.on_map_change = on_map_change
        self.states: dict[str, str] = {name: "active" for name in (*NAVIGATION_NODES, *LOCALIZATION_NODES)}
        self.nodes: dict[str, Node] = {}
        self._group = ReentrantCallbackGroup()
        ns = namespace.rstrip("/")

        def node(name: str, sub_namespace: str = "") -> Node:
            full_ns = f"{ns}/{sub_namespace}" if sub_namespace else (ns or "/")
            created = Node(name, namespace=full_ns, context=context, parameter_overrides=[], use_global_arguments=False)
            self.nodes[f"{sub_namespace}/{name}" if sub_namespace else name] = created
            if name in self.states:
                created.create_service(GetState, "~/get_state", self._get_state(name), callback_group=self._group)
            return created

        for name in NAVIGATION_NODES + LOCALIZATION_NODES:
            node(name)
        for manager, managed in (
            ("lifecycle_manager_navigation", NAVIGATION_NODES),
            ("lifecycle_manager_localization", LOCALIZATION_NODES),
        ):
            m = node(manager)
            m.create_service(ManageLifecycleNodes, "~/manage_nodes", self._manage(managed), callback_group=self._group)
            m.create_service(Trigger, "~/is_active", self._is_active(managed), callback_group=self._group)
        self.global_node = node("global_costmap", "global_costmap")
        self.local_node = node("local_costmap", "local_costmap")

        self.side = SideTasks(loop)  # tasks stepped beside the motion task: docking, route tracking
        self._setup_navigators()
        self._setup_planner()
        self._setup_controller_and_behaviors()
        self._setup_docking()
        self._setup_costmaps()
        self._setup_map_server()
        self._setup_amcl()

    def all_nodes(self) -> list[Node]:
        return list(self.nodes.values())

    # --- lifecycle ---------------------------------------------------------------------------------------------
    def _get_state(self, name: str) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            label = self.states[name]
            response.current_state = State(id=_STATES[label], label=label)
            return response

        return handler

    def _is_active(self, managed: tuple[str, ...]) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            response.success = all(self.states[n] == "active" for n in managed)
            response.message = ", ".join(f"{n}: {self.states[n]}" for n in managed)
            return response

        return handler

    def _manage(self, managed: tuple[str, ...]) -> Callable:
        transitions = {
            ManageLifecycleNodes.Request.STARTUP: "active",
            ManageLifecycleNodes.Request.RESUME: "active",
            ManageLifecycleNodes.Request.PAUSE: "inactive",
            ManageLifecycleNodes.Request.CONFIGURE: "inactive",
            ManageLifecycleNodes.Request.RESET: "unconfigured",
            ManageLifecycleNodes.Request.CLEANUP: "unconfigured",
            ManageLifecycleNodes.Request.SHUTDOWN: "finalized",
        }

        def handler(request: Any, response: Any) -> Any:
            target = transitions.get(request.command)
            if target is None:
                response.success = False
                return response
            for name in managed:
                # A finalized node stays finalized, except through STARTUP (what a relaunch would do).
                stuck = self.states[name] == "finalized" and target != "finalized"
                if stuck and request.command != ManageLifecycleNodes.Request.STARTUP:
                    continue
                self.states[name] = target
            if "bt_navigator" in managed:
                self.loop.call(self.nav.resume if target == "active" else self.nav.pause)
            response.success = True
            return response

        return handler

    def _active(self, name: str) -> Callable[[Any], bool]:
        def accept(_goal: Any) -> bool:
            ok = self.states.get(name) == "active"
            if not ok:
                self.nodes[name].get_logger().warn(f"goal rejected: {name} is {self.states.get(name)}, not active")
            return ok

        return accept

    # --- actions -----------------------------------------------------------------------------------------------
    def _action(self, owner: str, action_type: Any, name: str, start: Callable[[Any], Any], **kwargs: Any) -> None:
        TaskActionServer(
            self.nodes[owner],
            self.loop,
            action_type,
            name,
            start,
            stamp=lambda: self.loop.sim.time,
            accept=self._active(owner),
            record=self.record,
            **kwargs,
        )

    def _setup_navigators(self) -> None:
        A = nav2_action
        node = self.nodes["bt_navigator"]
        # Latched: a recorder or viewer that joins late (or whose discovery lags) still gets the current goals.
        self.goals_pub = node.create_publisher(Goals, "goals", LATCHED)

        def announce(poses: list[tuple[float, float, float]]) -> list[tuple[float, float, float]]:
            """Publish the goal poses on `goals` (recordings and viewers show them), then hand them on."""
            msg = Goals()
            msg.header.frame_id = "map"
            msg.header.stamp = time_msg(self.loop.sim.time)
            msg.goals = [pose_stamped(p, self.loop.sim.time) for p in poses]
            self.goals_pub.publish(msg)
            return poses

        self._action(
            "bt_navigator",
            A.NavigateToPose,
            "navigate_to_pose",
            lambda g: self.nav.start_navigate_to_pose(announce([checked_pose(g.pose, "goal pose")])[0]),
            invalid_code=result_code(A.NavigateToPose, "UNKNOWN"),
        )
        self._action(
            "bt_navigator",
            A.NavigateThroughPoses,
            "navigate_through_poses",
            lambda g: self.nav.start_navigate_through_poses(announce(_poses(get_poses(g, "poses")))),
            invalid_code=result_code(A.NavigateThroughPoses, "UNKNOWN"),
        )
        self._action(
            "waypoint_follower",
            A.FollowWaypoints,
            "follow_waypoints",
            lambda g: self.nav.start_follow_waypoints(
                announce(_poses(g.poses)), int(g.number_of_loops), int(g.goal_index)
            ),
            invalid_code=result_code(A.FollowWaypoints, "NO_VALID_WAYPOINTS"),
        )
        # Like Nav2's bt_navigator: a PoseStamped on goal_pose (RViz's "Nav2 Goal" tool) becomes a
        # navigate_to_pose goal, sent through the action so feedback and results flow as usual.
        self._goal_pose_client: ActionClient = ActionClient(
            node, A.NavigateToPose, "navigate_to_pose", callback_group=self._group
        )

        def on_goal_pose(msg: PoseStamped) -> None:
            try:
                checked_pose(msg, "goal_pose")
            except ValueError as exc:
                node.get_logger().warn(f"goal_pose ignored: {exc}")
                return
            self._goal_pose_client.send_goal_async(A.NavigateToPose.Goal(pose=msg))

        node.create_subscription(PoseStamped, "goal_pose", on_goal_pose, 10, callback_group=self._group)

    def _setup_planner(self) -> None:
        A = nav2_action
        self.plan_pub = self.nodes["planner_server"].create_publisher(PathMsg, "plan", 1)

        def compute(goal: Any, through: bool) -> ImmediateTask:
            code_of = to_through_poses_code if through else to_path_code
            if goal.planner_id not in PLANNER_IDS:
                return ImmediateTask(
                    False,
                    {
                        "error_code": code_of(PlanError.INVALID_PLANNER),
                        "error_msg": f"unknown planner_id '{goal.planner_id}' (known: GridBased)",
                    },
                )
            try:
                start = checked_pose(goal.start, "start pose") if goal.use_start else None
                if through:
                    targets = _poses(get_poses(goal, "goals"), allow_empty=True)
                    result = self.nav.compute_path_through(start, targets)
                else:
                    result = self.nav.compute_path(start, checked_pose(goal.goal, "goal pose"))
            except NotLocalizedError as exc:
                return ImmediateTask(False, {"error_code": 302 if through else 202, "error_msg": str(exc)})
            except ValueError as exc:
                error = PlanError.GOAL_OUTSIDE_MAP if "goal" in str(exc) else PlanError.START_OUTSIDE_MAP
                return ImmediateTask(False, {"error_code": code_of(error), "error_msg": str(exc)})
            fields: dict[str, Any] = {"planning_time": result.planning_time, "error_msg": result.message}
            if result.ok:
                fields["path"] = result.path
                self.plan_pub.publish(path_msg(result.path, self.loop.sim.time))
            fields["error_code"] = code_of(result.error)
            return ImmediateTask(result.ok, fields)

        self._action("planner_server", A.ComputePathToPose, "compute_path_to_pose", lambda g: compute(g, False))
        self._action(
            "planner_server", A.ComputePathThroughPoses, "compute_path_through_poses", lambda g: compute(g, True)
        )
        self.nav_plan_listener()

        def is_path_valid(request: Any, response: Any) -> Any:
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

        self.nodes["planner_server"].create_service(
            IsPathValid, "is_path_valid", is_path_valid, callback_group=self._group
        )

        def smooth(goal: Any) -> ImmediateTask:
            A_ = nav2_action.SmoothPath.Result
            if goal.smoother_id not in SMOOTHER_IDS:
                return ImmediateTask(
                    False, {"error_code": A_.INVALID_SMOOTHER, "error_msg": f"unknown smoother_id '{goal.smoother_id}'"}
                )
            path = path_to_array(goal.path)
            if len(path) < 2:
                return ImmediateTask(
                    False, {"error_code": A_.INVALID_PATH, "error_msg": "a path needs at least 2 poses"}
                )
            max_duration = duration_to_seconds(goal.max_smoothing_duration) or 2.0
            result = self.nav.smooth(path, max_duration, bool(goal.check_for_collisions))
            fields = {
                "path": result.path,
                "smoothing_duration": getattr(result, "duration", 0.0),
                "was_completed": bool(result.was_completed),
            }
            if goal.check_for_collisions and result.in_collision:
                fields.update(error_code=A_.SMOOTHED_PATH_IN_COLLISION, error_msg="smoothed path is in collision")
                return ImmediateTask(False, fields)
            return ImmediateTask(True, fields)

        self._action("smoother_server", A.SmoothPath, "smooth_path", smooth)

    def nav_plan_listener(self) -> None:
        """Publish each new global plan of the running navigation task on `plan` (RViz shows it)."""
        last: dict[str, Any] = {"path": None}

        def publish(now: float) -> None:
            task = self.nav.task
            path = getattr(task, "path", None) if task is not None else None
            if path is None or len(path) == 0 or path is last["path"]:
                return
            last["path"] = path  # a new plan is a new array: identity tells us when to publish
            if self.plan_pub.get_subscription_count() > 0:  # building a Path message costs ~10 ms: only if watched
                self.plan_pub.publish(path_msg(path, now))
            if self.record is not None:
                self.record.plan(now, path)

        self.loop.every(0.1, publish)

    def _setup_controller_and_behaviors(self) -> None:
        A = nav2_action

        def follow_path(goal: Any) -> Any:
            if goal.controller_id not in CONTROLLER_IDS:
                return ImmediateTask(
                    False,
                    {
                        "error_code": A.FollowPath.Result.INVALID_CONTROLLER,
                        "error_msg": f"unknown controller_id '{goal.controller_id}'",
                    },
                )
            path = path_to_array(goal.path)
            if len(path) == 0:
                return ImmediateTask(False, {"error_code": A.FollowPath.Result.INVALID_PATH, "error_msg": "empty path"})
            return self.nav.start_follow_path(path)

        self._action("controller_server", A.FollowPath, "follow_path", follow_path)
        b = "behavior_server"
        self._action(
            b,
            A.Spin,
            "spin",
            lambda g: self.nav.start_spin(
                _finite(g.target_yaw, "target_yaw"),
                duration_to_seconds(g.time_allowance),
                bool(get_optional(g, "disable_collision_checks", False)),
            ),
            invalid_code=A.Spin.Result.UNKNOWN,
        )
        self._action(
            b,
            A.BackUp,
            "backup",
            lambda g: self.nav.start_backup(*_straight_line(g)),
            invalid_code=A.BackUp.Result.INVALID_INPUT,
        )
        self._action(
            b,
            A.DriveOnHeading,
            "drive_on_heading",
            lambda g: self.nav.start_drive_on_heading(*_straight_line(g)),
            invalid_code=A.DriveOnHeading.Result.INVALID_INPUT,
        )
        self._action(
            b,
            A.Wait,
            "wait",
            lambda g: self.nav.start_wait(duration_to_seconds(g.time)),
            invalid_code=result_code(A.Wait, "UNKNOWN"),
        )
        self._action(
            b,
            A.AssistedTeleop,
            "assisted_teleop",
            lambda g: self.nav.start_assisted_teleop(duration_to_seconds(g.time_allowance)),
            invalid_code=A.AssistedTeleop.Result.UNKNOWN,
        )
        node = self.nodes[b]

        def teleop(msg: Twist) -> None:
            v, w = msg.linear.x, msg.angular.z
            if math.isfinite(v) and math.isfinite(w):
                self.loop.call(lambda: self.nav.teleop_velocity(v, w))

        node.create_subscription(Twist, "cmd_vel_teleop", teleop, 10, callback_group=self._group)

        def preempt(_msg: Empty) -> None:
            self.loop.call(self.nav.preempt_teleop)

        node.create_subscription(Empty, "preempt_teleop", preempt, 10, callback_group=self._group)

    def _setup_docking(self) -> None:
        """Nav2's docking_server actions over the Create 3 dock (tb4.ros.docking)."""
        self.docking = DockingServer(self, self.side)

    # --- costmaps ----------------------------------------------------------------------------------------------
    def _setup_costmaps(self) -> None:
        g, lo = self.global_node, self.local_node
        grp = self._group

        def clear(fn: Callable[[], None]) -> Callable:
            def handler(_request: Any, response: Any) -> Any:
                self.loop.call(fn)
                return response

            return handler

        def distance_clear(fn: Callable[[float], None]) -> Callable:
            def handler(request: Any, response: Any) -> Any:
                d = float(request.reset_distance)
                if math.isfinite(d) and d >= 0:
                    self.loop.call(lambda: fn(d))
                return response

            return handler

        g.create_service(
            ClearEntireCostmap, "clear_entirely_global_costmap", clear(self.nav.clear_global), callback_group=grp
        )
        lo.create_service(
            ClearEntireCostmap, "clear_entirely_local_costmap", clear(self.nav.clear_local), callback_group=grp
        )
        lo.create_service(
            ClearCostmapExceptRegion,
            "clear_costmap_except_region",
            distance_clear(self.nav.clear_local_except),
            callback_group=grp,
        )
        lo.create_service(
            ClearCostmapAroundRobot,
            "clear_costmap_around_robot",
            distance_clear(self.nav.clear_local_around),
            callback_group=grp,
        )
        for srv, name, fn in (
            (ClearCostmapExceptRegion, "clear_costmap_except_region", self.nav.clear_global_except),
            (ClearCostmapAroundRobot, "clear_costmap_around_robot", self.nav.clear_global_around),
        ):
            g.create_service(srv, name, distance_clear(fn), callback_group=grp)
        g.create_service(GetCostmap, "get_costmap", self._get_costmap("global"), callback_group=grp)
        lo.create_service(GetCostmap, "get_costmap", self._get_costmap("local"), callback_group=grp)
        self.global_pub = g.create_publisher(OccupancyGrid, "costmap", LATCHED)
        self.local_pub = lo.create_publisher(OccupancyGrid, "costmap", 1)
        self._published_global: Any = None
        self.loop.every(1.0, self._publish_global_costmap)
        self.loop.every(0.5, self._publish_local_costmap)

    def _costmap(self, which: str) -> Any:
        if which == "global":
            return self.nav.global_costmap.costmap
        return self.nav.current_local_costmap()

    def _get_costmap(self, which: str) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            def snapshot() -> tuple[Any, float]:
                return self._costmap(which).copy(), self.loop.sim.time

            costmap, now = self.loop.call(snapshot)
            msg = Costmap()
            msg.header.frame_id = "map" if (which == "global" or self.nav.localizer.is_localized) else "odom"
            msg.header.stamp = time_msg(now)
            meta = CostmapMetaData()
            meta.map_load_time = time_msg(0.0)
            meta.update_time = time_msg(now)
            meta.layer = "master"
            meta.resolution = float(costmap.resolution)
            meta.size_y, meta.size_x = (int(n) for n in costmap.data.shape)
            meta.origin = pose_msg(costmap.origin_x, costmap.origin_y, 0.0)
            msg.metadata = meta
            msg.data = costmap.data.ravel().tobytes()
            response.map = msg
            return response

        return handler

    def _costmap_grid(self, costmap: Any, now: float, frame: str) -> OccupancyGrid:
        grid = OccupancyMap(
            data=costmap_to_occupancy_values(costmap),
            resolution=costmap.resolution,
            origin_x=costmap.origin_x,
            origin_y=costmap.origin_y,
        )
        return occupancy_grid_msg(grid, now, frame)

    def _publish_global_costmap(self, now: float) -> None:
        costmap = self.nav.global_costmap.costmap
        if costmap is self._published_global:
            return
        self._published_global = costmap
        self.global_pub.publish(self._costmap_grid(costmap, now, "map"))

    def _publish_local_costmap(self, now: float) -> None:
        if self.local_pub.get_subscription_count() == 0:
            return
        frame = "map" if self.nav.localizer.is_localized else "odom"
        self.local_pub.publish(self._costmap_grid(self._costmap("local"), now, frame))

    # --- map server and localization -------------------------------------------------------------------------
    def _setup_map_server(self) -> None:
        node = self.nodes["map_server"]
        self.map_pub = node.create_publisher(OccupancyGrid, "map", LATCHED)
        self.publish_map(self.nav.grid, 0.0)

        def load(request: Any, response: Any) -> Any:
            url = request.map_url
            path = Path(url[len("file://") :] if url.startswith("file://") else url)
            if not path.is_file():
                response.result = LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST
                node.get_logger().error(f"load_map: no such map file: {path}")
                return response
            try:
                grid = load_map(path)
            except ConfigError as exc:
                bad_image = exc.key == "image"
                response.result = (
                    LoadMap.Response.RESULT_INVALID_MAP_DATA
                    if bad_image
                    else LoadMap.Response.RESULT_INVALID_MAP_METADATA
                )
                node.get_logger().error(f"load_map: {exc}")
                return response

            def switch() -> float:
                self.loop.sim.set_grid(grid)
                self.nav.set_map(grid)
                return self.loop.sim.time

            now = self.loop.call(switch)
            msg = self.publish_map(grid, now)
            if self.on_map_change is not None:
                self.on_map_change(grid, path)
            response.map = msg
            response.result = LoadMap.Response.RESULT_SUCCESS
            node.get_logger().info(f"switched to map {path}")
            return response

        node.create_service(LoadMap, "~/load_map", load, callback_group=self._group)

    def publish_map(self, grid: OccupancyMap, now: float) -> OccupancyGrid:
        msg = occupancy_grid_msg(grid, now)
        self.map_pub.publish(msg)
        return msg

    def _setup_amcl(self) -> None:
        self.amcl = AmclInterfaces(self.nodes["amcl"], self.loop, self.states, self._group)


def _straight_line(goal: Any) -> tuple[float, float, float, bool, float, float]:
    """BackUp / DriveOnHeading goal -> (distance, speed, time_allowance, disable_collision_checks, y, z)."""
    return (
        _finite(goal.target.x, "target.x"),
        _finite(goal.speed, "speed"),
        duration_to_seconds(goal.time_allowance),
        bool(get_optional(goal, "disable_collision_checks", False)),
        _finite(goal.target.y, "target.y"),
        _finite(goal.target.z, "target.z"),
    )


def _finite(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise ValueError(f"{what} must be finite, got {value}")
    return float(value)


def _poses(poses: Any, allow_empty: bool = False) -> list[tuple[float, float, float]]:
    result = [checked_pose(p, f"pose {i}") for i, p in enumerate(poses)]
    if not result and not allow_empty:
        raise ValueError("no poses given")
    return result
