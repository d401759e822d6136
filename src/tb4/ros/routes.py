"""Nav2's route server in the simulator: compute_route, compute_and_track_route, set_route_graph, route_graph.

The graph is the world's GeoJSON route graph (tb4.nav.route_graph); planning and tracking are tb4.nav's
RoutePlanner and RouteTrackingTask. Tracking feedback carries every event (new route, node passed, arrival)
and the current state in between, as Nav2's tracker does; `rerouted` is set once per route, so a client that
re-sends `feedback.path` to FollowPath whenever it is set does so once per route. Services: set_route_graph,
DynamicEdgesScorer/adjust_edges and ReroutingService/reroute, as Nav2's default plugins offer them.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import Point
from nav2_msgs import action as nav2_action
from nav2_msgs.msg import Route as RouteMsg
from nav2_msgs.msg import RouteEdge as RouteEdgeMsg
from nav2_msgs.msg import RouteNode as RouteNodeMsg
from nav2_msgs.srv import DynamicEdges, SetRouteGraph
from std_srvs.srv import Trigger
from visualization_msgs.msg import Marker, MarkerArray

from tb4.config import ConfigError
from tb4.nav.route_graph import RouteGraph, load_route_graph
from tb4.nav.route_planner import Route, RouteError, RoutePlanner, RouteRequest
from tb4.nav.route_tracker import RouteTrackingTask
from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import path_msg, pose_to_tuple, time_msg
from tb4.ros.qos import LATCHED
from tb4.ros.replies import create_service
from tb4.ros.side_tasks import SideTasks

__all__ = ["RouteServer", "route_msg"]


def route_msg(route: Route, graph: RouteGraph, stamp: float) -> RouteMsg:
    msg = RouteMsg()
    msg.header.frame_id = "map"
    msg.header.stamp = time_msg(stamp)
    msg.route_cost = float(route.cost)
    nodes = graph.nodes
    msg.nodes = [RouteNodeMsg(nodeid=n, position=Point(x=nodes[n].x, y=nodes[n].y)) for n in route.node_ids]
    msg.edges = [
        RouteEdgeMsg(
            edgeid=e.id,
            start=Point(x=nodes[e.start].x, y=nodes[e.start].y),
            end=Point(x=nodes[e.end].x, y=nodes[e.end].y),
        )
        for e in route.edges
    ]
    return msg


def graph_markers(graph: RouteGraph | None, stamp: float) -> MarkerArray:
    """The graph as RViz markers (one LINE_LIST of edges, one SPHERE_LIST of nodes), like Nav2's route_graph."""
    out = MarkerArray()
    if graph is None:
        out.markers = [Marker(action=Marker.DELETEALL)]
        return out
    edges = Marker(ns="route_graph_edges", id=0, type=Marker.LINE_LIST, action=Marker.ADD)
    nodes = Marker(ns="route_graph_nodes", id=1, type=Marker.SPHERE_LIST, action=Marker.ADD)
    for marker, size in ((edges, 0.05), (nodes, 0.2)):
        marker.header.frame_id = "map"
        marker.header.stamp = time_msg(stamp)
        marker.scale.x = marker.scale.y = marker.scale.z = size
        marker.color.r, marker.color.g, marker.color.b, marker.color.a = 0.15, 0.65, 0.6, 1.0
        marker.pose.orientation.w = 1.0
    for x0, y0, x1, y1 in graph.segments():
        edges.points += [Point(x=x0, y=y0), Point(x=x1, y=y1)]
    nodes.points = [Point(x=n.x, y=n.y) for n in graph.nodes.values()]
    out.markers = [edges, nodes]
    return out


class RouteServer:
    """The route_server node of `nav2` (a tb4.ros.nav2.Nav2Interfaces) serving the world's route graph."""

    def __init__(self, nav2: Any, graph: RouteGraph | None, side: SideTasks) -> None:
        self.nav2 = nav2
        self.loop = nav2.loop
        self.side = side
        self.params = nav2.nav.params.section("route_server", "ros__parameters")
        self.node = nav2.nodes["route_server"]
        self.graph: RouteGraph | None = None
        self.planner: RoutePlanner | None = None
        self.graph_error = "no route graph: this world has none (set one with the set_route_graph service)"
        self.graph_pub = self.node.create_publisher(MarkerArray, "route_graph", LATCHED)
        self.route_pub = self.node.create_publisher(RouteMsg, "route", 1)
        if graph is not None:
            self._use(graph, str(graph.source))
        A = nav2_action
        nav2.serve_action("route_server", A.ComputeRoute, "compute_route", self._compute, invalid_code=400)
        nav2.serve_action(
            "route_server",
            A.ComputeAndTrackRoute,
            "compute_and_track_route",
            self._track,
            invalid_code=400,
            feedback_fields=self._tracking_feedback,
            result_fields=lambda task: task.result(),
        )
        create_service(self.node, SetRouteGraph, "set_route_graph", self._set_graph, callback_group=nav2.callback_group)
        create_service(
            self.node,
            DynamicEdges,
            "~/DynamicEdgesScorer/adjust_edges",
            self._adjust_edges,
            callback_group=nav2.callback_group,
        )
        create_service(
            self.node, Trigger, "~/ReroutingService/reroute", self._reroute, callback_group=nav2.callback_group
        )
        self._msg_cache: dict[int, tuple[Any, Any, Any]] = {}  # id(route) -> (route, Route msg, Path msg)

    # --- graph -------------------------------------------------------------------------------------------
    def _load(self, path: str) -> bool:
        try:
            graph = load_route_graph(path)
        except ConfigError as exc:
            self.node.get_logger().error(f"failed to load route graph: {exc}")
            return False
        self._use(graph, path)
        return True

    def _use(self, graph: RouteGraph, path: str) -> None:
        self.graph, self.planner = graph, RoutePlanner(graph, self.params)
        self.graph_pub.publish(graph_markers(graph, self.loop.sim.time))
        self.node.get_logger().info(f"route graph {path}: {len(graph.nodes)} nodes, {len(graph.edges)} edges")

    def _set_graph(self, request: Any, response: Any) -> Any:
        """SetRouteGraph: like Nav2, a failed load leaves no graph (requests then fail with NO_VALID_GRAPH)."""

        def swap() -> bool:
            for task in self.side.running(RouteTrackingTask):
                task.cancel()
            self.graph, self.planner = None, None
            ok = self._load(request.graph_filepath)
            if not ok:
                self.graph_error = f"no valid route graph: failed to load {request.graph_filepath}"
                self.graph_pub.publish(graph_markers(None, self.loop.sim.time))
            return ok

        response.success = bool(self.loop.call(swap))
        return response

    def _reroute(self, _request: Any, response: Any) -> Any:
        """ReroutingService: the running tracking goal recomputes its route from the last node passed."""

        def request() -> int:
            tasks = self.side.running(RouteTrackingTask)
            for task in tasks:
                task.request_reroute()
            return len(tasks)

        count = self.loop.call(request)
        response.success = True  # as Nav2's: the request is noted even when nothing is being tracked
        response.message = f"reroute requested ({count} route(s) tracked)"
        return response

    def _adjust_edges(self, request: Any, response: Any) -> Any:
        """DynamicEdgesScorer's service: close, reopen and re-cost edges for the next routes (and reroutes)."""
        costs = {int(e.edgeid): float(e.cost) for e in request.adjust_edges}

        def apply() -> bool:
            if self.planner is None:
                return False
            try:
                self.planner.adjust_edges(list(request.closed_edges), list(request.opened_edges), costs)
            except ValueError as exc:
                self.node.get_logger().warn(f"adjust_edges refused: {exc}")
                return False
            return True

        response.success = bool(self.loop.call(apply))
        return response

    # --- requests ----------------------------------------------------------------------------------------
    def _request(self, goal: Any, robot_pose: tuple[float, float, float] | None) -> RouteRequest:
        if not goal.use_poses:
            return RouteRequest(start_id=int(goal.start_id), goal_id=int(goal.goal_id))
        for what, stamped in (("goal", goal.goal), ("start", goal.start)):
            if what == "start" and not goal.use_start:
                continue
            if stamped.header.frame_id not in ("", "map"):
                raise RouteError(
                    "TF_ERROR", f"cannot transform the {what} pose from frame '{stamped.header.frame_id}' to 'map'"
                )
        start = pose_to_tuple(goal.start) if goal.use_start else robot_pose
        return RouteRequest(start=start, goal=pose_to_tuple(goal.goal), use_poses=True)

    def _compute(self, goal: Any) -> ImmediateTask:
        began = self.loop.sim.time
        if self.planner is None or self.graph is None:
            return ImmediateTask.failure(402, self.graph_error)
        try:
            costmap = self.nav2.nav.planning_costmap()
            request = self._request(goal, self.nav2.nav.pose())
            route = self.planner.find_route(request, None, costmap)
            path = self.planner.densify(route)
        except RouteError as exc:
            self.node.get_logger().warn(f"compute_route failed: {exc}")
            return ImmediateTask.failure(exc.code, str(exc))
        now = self.loop.sim.time
        self._publish(route, path, now)
        return ImmediateTask(
            True,
            {"path": path_msg(path, now), "route": route_msg(route, self.graph, now), "planning_time": now - began},
        )

    def _track(self, goal: Any) -> Any:
        for task in self.side.running(RouteTrackingTask):
            task.cancel()  # one tracking goal at a time: a new one preempts the old
        if self.planner is None or self.graph is None:
            return ImmediateTask.failure(402, self.graph_error)
        task = RouteTrackingTask(self.planner, lambda pose: self._request(goal, pose))
        nav = self.nav2.nav
        return self.loop.call_outside_replay(
            lambda: self.side.add(
                task, lambda now: task.step(nav.pose(), nav.current_local_costmap, now, nav.planning_costmap)
            ),
            "route tracking (it watches the robot, which the client drives)",
            moves=False,
        )

    def _tracking_feedback(self, task: RouteTrackingTask) -> dict[str, Any] | None:
        """Events first (new route, node passed, arrival); between them the current state, as Nav2's tracker
        sends every cycle while its query operations run. Messages are built once per route."""
        event = task.next_feedback() or task.state_feedback()
        if event is None or self.graph is None:
            return None
        now = self.loop.sim.time
        if event["rerouted"]:
            self._publish(event["route"], event["path"], now)
        cached = self._msg_cache.get(id(event["route"]))
        if cached is None or cached[0] is not event["route"]:
            cached = (event["route"], route_msg(event["route"], self.graph, now), path_msg(event["path"], now))
            self._msg_cache = {id(event["route"]): cached}
        fields = dict(event)
        fields["route"], fields["path"] = cached[1], cached[2]
        return fields

    def _publish(self, route: Route, path: Any, now: float) -> None:
        if self.graph is not None and self.route_pub.get_subscription_count() > 0:
            self.route_pub.publish(route_msg(route, self.graph, now))
        self.nav2.planner.publish_plan(path, now)
