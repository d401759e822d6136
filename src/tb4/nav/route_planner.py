"""Route planning over a route graph with Nav2 route server's semantics (ComputeRoute).

Start and goal are node ids, or poses mapped to the nearest node (with a line-of-sight check on the costmap
standing in for Nav2's breadth-first node search). The search is Dijkstra over directed edges; an edge costs
its file `cost` when it is not `overridable`, else the sum of the scorers: DistanceScorer (length divided by the
edge's `speed_limit` metadata, times its weight) and PenaltyScorer (the edge's `penalty` metadata times its
weight). Blocked edges (and edges into blocked nodes) are skipped, as when the tracker reroutes. With poses,
the first / last edge is pruned when the robot / goal already lies along it, like Nav2's goal intent extractor.
The route then becomes a dense (N, 3) path at `path_density`, headings along the edges.
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tb4.core.geometry import Pose
from tb4.nav.costmap import INSCRIBED, NO_INFORMATION, Costmap2D
from tb4.nav.route_graph import RouteEdge, RouteGraph

__all__ = [
    "ROUTE_ERROR_CODES",
    "RouteError",
    "Route",
    "RouteRequest",
    "ReroutingState",
    "RoutePlanner",
    "DEFAULT_ROUTE_PARAMS",
    "closest_point",
    "normalized_dot",
    "line_blocked",
]

ROUTE_ERROR_CODES = {
    "UNKNOWN": 400,
    "TF_ERROR": 401,
    "NO_VALID_GRAPH": 402,
    "INDETERMINANT_NODES_ON_GRAPH": 403,
    "TIMEOUT": 404,
    "NO_VALID_ROUTE": 405,
    "OPERATION_FAILED": 406,
    "INVALID_EDGE_SCORER_USE": 407,
}

# route_server parameters (upstream names and defaults); params/nav2.yaml's route_server section overrides them
DEFAULT_ROUTE_PARAMS: dict[str, Any] = {
    "max_iterations": 0,
    "max_planning_time": 2.0,
    "path_density": 0.05,
    "prune_goal": True,
    "max_prune_dist_from_edge": 8.0,
    "min_prune_dist_from_goal": 0.15,
    "min_prune_dist_from_start": 0.10,
    "enable_nn_search": True,
    "num_nearest_nodes": 5,
    "radius_to_achieve_node": 2.0,
    "boundary_radius_to_achieve_node": 1.0,
    "aggregate_blocked_ids": False,
    "DistanceScorer": {"weight": 1.0},
    "PenaltyScorer": {"weight": 1.0},
    "CollisionMonitor": {"rate": 1.0, "max_cost": 253.0, "max_collision_dist": 5.0, "reroute_on_collision": True},
}

_EPS = 1e-5


class RouteError(Exception):
    """A route request that cannot be served; `code` is the ComputeRoute result error code."""

    def __init__(self, kind: str, message: str) -> None:
        super().__init__(message)
        self.kind = kind
        self.code = ROUTE_ERROR_CODES[kind]


@dataclass
class Route:
    """A start node and the edges leading from it; `cost` is the summed traversal cost."""

    start_node: int
    edges: list[RouteEdge]
    cost: float = 0.0

    @property
    def node_ids(self) -> list[int]:
        return [self.start_node, *(e.end for e in self.edges)]


@dataclass(frozen=True)
class RouteRequest:
    """ComputeRoute / ComputeAndTrackRoute goal in core terms (poses in the map frame)."""

    start_id: int = 0
    goal_id: int = 0
    start: Pose | None = None  # the pose to start from (goal.start with use_start, else the robot's pose)
    goal: Pose | None = None
    use_poses: bool = False


@dataclass
class ReroutingState:
    """What tracking hands back to planning when it asks for a reroute (Nav2's ReroutingState)."""

    blocked_ids: list[int] = field(default_factory=list)
    rerouting_start_id: int | None = None
    rerouting_start_pose: Pose | None = None
    curr_edge: RouteEdge | None = None
    closest_pt_on_edge: tuple[float, float] | None = None
    first_time: bool = True


def _merged(params: Mapping[str, Any] | None) -> dict[str, Any]:
    out = {k: (dict(v) if isinstance(v, dict) else v) for k, v in DEFAULT_ROUTE_PARAMS.items()}
    for k, v in (params or {}).items():
        if isinstance(v, Mapping) and isinstance(out.get(k), dict):
            out[k].update(v)
        else:
            out[k] = v
    return out


def closest_point(px: float, py: float, ax: float, ay: float, bx: float, by: float) -> tuple[float, float]:
    """The point of segment a-b closest to p."""
    vx, vy = bx - ax, by - ay
    denom = vx * vx + vy * vy
    t = 0.0 if denom <= 0.0 else min(1.0, max(0.0, ((px - ax) * vx + (py - ay) * vy) / denom))
    return ax + t * vx, ay + t * vy


def normalized_dot(ax: float, ay: float, bx: float, by: float) -> float:
    na, nb = math.hypot(ax, ay), math.hypot(bx, by)
    if na < 1e-9 or nb < 1e-9:
        return 0.0
    return (ax * bx + ay * by) / (na * nb)


class RoutePlanner:
    """Plans routes on one graph; `costmap` (optional) enables the line-of-sight node search."""

    def __init__(self, graph: RouteGraph, params: Mapping[str, Any] | None = None) -> None:
        self.graph = graph
        self.params = _merged(params)
        self.closed_edges: set[int] = set()  # DynamicEdgesScorer: edges closed at run time
        self.dynamic_penalties: dict[int, float] = {}  # ... and their run-time cost adjustments

    def adjust_edges(self, closed: Sequence[int], opened: Sequence[int], costs: Mapping[int, float]) -> None:
        """DynamicEdges service: close / reopen edges, set extra costs (all or nothing on a bad cost)."""
        for edge_id, cost in costs.items():
            if not (math.isfinite(cost) and cost >= 0.0):
                raise ValueError(f"edge {edge_id}: cost must be a finite number >= 0, got {cost}")
        self.closed_edges.update(int(e) for e in closed)
        self.closed_edges.difference_update(int(e) for e in opened)
        self.dynamic_penalties.update({int(k): float(v) for k, v in costs.items()})

    # --- cost ------------------------------------------------------------------------------------------
    def edge_cost(self, edge: RouteEdge) -> float | None:
        """Traversal cost of an edge (nav2_route's RoutePlanner::getTraversalCost with our scorers); None when a
        scorer refuses it (DynamicEdgesScorer: closed). A non-overridable edge keeps its file cost."""
        if not edge.overridable:
            if edge.cost <= 0.0:
                raise RouteError("NO_VALID_GRAPH", f"edge {edge.id} has no valid cost and may not be scored")
            return edge.cost
        if edge.id in self.closed_edges:
            return None
        speed = float(edge.metadata.get("speed_limit", 1.0))
        penalty = float(edge.metadata.get("penalty", 0.0))
        return (
            float(self.params["DistanceScorer"]["weight"]) * self.graph.length(edge) / speed
            + float(self.params["PenaltyScorer"]["weight"]) * penalty
            + self.dynamic_penalties.get(edge.id, 0.0)
        )

    def _cost(self, edge: RouteEdge) -> float:
        cost = self.edge_cost(edge)
        return 0.0 if cost is None else cost

    # --- start / goal ----------------------------------------------------------------------------------
    def _node_for_pose(self, pose: Pose, what: str, costmap: Costmap2D | None) -> int:
        x, y = float(pose[0]), float(pose[1])
        if not (math.isfinite(x) and math.isfinite(y)):
            raise RouteError("INDETERMINANT_NODES_ON_GRAPH", f"the {what} pose is not finite: ({x}, {y})")
        if costmap is not None and not costmap.in_bounds(x, y):
            raise RouteError(
                "INDETERMINANT_NODES_ON_GRAPH",
                f"could not determine the node closest to the {what} pose ({x:.2f}, {y:.2f}): it is outside the map",
            )
        candidates = self.graph.nearest_nodes(x, y, int(self.params["num_nearest_nodes"]))
        if costmap is None or not self.params["enable_nn_search"] or len(candidates) < 2:
            return candidates[0]
        for node_id in candidates:  # nearest first: the first one the robot can see in a straight line
            node = self.graph.nodes[node_id]
            if not line_blocked(costmap, x, y, node.x, node.y, INSCRIBED):
                return node_id
        return candidates[0]

    def find_start_and_goal(self, request: RouteRequest, costmap: Costmap2D | None = None) -> tuple[int, int]:
        if not request.use_poses:
            for what, node_id in (("start", request.start_id), ("goal", request.goal_id)):
                if node_id not in self.graph.nodes:
                    known = sorted(self.graph.nodes)
                    shown = ", ".join(map(str, known[:12])) + (" ..." if len(known) > 12 else "")
                    raise RouteError("UNKNOWN", f"{what} node id {node_id} is not in the route graph (ids: {shown})")
            return request.start_id, request.goal_id
        if request.start is None or request.goal is None:
            raise RouteError("TF_ERROR", "no start pose: the robot is not localized and use_start is false")
        return self._node_for_pose(request.start, "start", costmap), self._node_for_pose(request.goal, "goal", costmap)

    # --- search ----------------------------------------------------------------------------------------
    def search(self, start: int, goal: int, blocked: Sequence[int] = ()) -> Route:
        """Dijkstra from node `start` to node `goal`, skipping blocked edges and nodes."""
        if start == goal:
            return Route(start, [], 0.0)
        blocked_set = set(int(b) for b in blocked)
        best: dict[int, float] = {start: 0.0}
        parent: dict[int, RouteEdge] = {}
        queue: list[tuple[float, int]] = [(0.0, start)]
        limit = int(self.params["max_iterations"]) or math.inf
        max_time = float(self.params["max_planning_time"])
        started = time.monotonic()
        iterations = 0
        while queue:
            iterations += 1
            if iterations > limit:
                raise RouteError("TIMEOUT", f"maximum iterations ({limit}) exceeded")
            if max_time > 0.0 and iterations % 1024 == 0 and time.monotonic() - started > max_time:
                raise RouteError("TIMEOUT", f"route search took more than max_planning_time ({max_time} s)")
            cost, node = heapq.heappop(queue)
            if cost > best.get(node, math.inf):
                continue
            if node == goal:
                break
            for edge in self.graph.outgoing[node]:
                if edge.id in blocked_set or edge.end in blocked_set:
                    continue
                step = self.edge_cost(edge)
                if step is None:
                    continue
                new_cost = cost + step
                if new_cost < best.get(edge.end, math.inf):
                    best[edge.end] = new_cost
                    parent[edge.end] = edge
                    heapq.heappush(queue, (new_cost, edge.end))
        if goal not in parent:
            raise RouteError("NO_VALID_ROUTE", f"could not find a route from node {start} to node {goal}")
        edges: list[RouteEdge] = []
        node = goal
        while node != start:
            edge = parent[node]
            edges.append(edge)
            node = edge.start
        edges.reverse()
        return Route(start, edges, best[goal])

    def find_route(
        self, request: RouteRequest, state: ReroutingState | None = None, costmap: Costmap2D | None = None
    ) -> Route:
        """The whole ComputeRoute: start/goal nodes, search (from the reroute start when rerouting), pruning."""
        state = state if state is not None else ReroutingState()
        start_node, goal_node = self.find_start_and_goal(request, costmap)
        a, b = self.graph.nodes[start_node], self.graph.nodes[goal_node]
        start_pose: Pose = (a.x, a.y, 0.0)
        goal_pose: Pose = (b.x, b.y, 0.0)
        if request.use_poses and request.start is not None and request.goal is not None:
            start_pose, goal_pose = request.start, request.goal
        if state.rerouting_start_id is not None:
            start_node = state.rerouting_start_id
            if state.rerouting_start_pose is not None:
                start_pose = state.rerouting_start_pose
        route = self.search(start_node, goal_node, state.blocked_ids)
        return self._prune(route, request.use_poses, start_pose, goal_pose, state)

    def _prune(self, route: Route, use_poses: bool, start: Pose, goal: Pose, state: ReroutingState) -> Route:
        last_curr_edge, state.curr_edge = state.curr_edge, None
        first_time, state.first_time = state.first_time, False
        if not route.edges or (not use_poses and first_time):
            return route
        edges = list(route.edges)
        cost = route.cost
        start_node = route.start_node
        nodes = self.graph.nodes
        first, nxt = nodes[start_node], nodes[edges[0].end]
        vpx, vpy = start[0] - first.x, start[1] - first.y
        cx, cy = closest_point(start[0], start[1], first.x, first.y, nxt.x, nxt.y)
        if (
            normalized_dot(nxt.x - first.x, nxt.y - first.y, vpx, vpy) > _EPS
            and math.hypot(vpx, vpy) > float(self.params["min_prune_dist_from_start"])
            and math.hypot(cx - start[0], cy - start[1]) <= float(self.params["max_prune_dist_from_edge"])
        ):
            if last_curr_edge is not None and last_curr_edge.id == edges[0].id:
                state.closest_pt_on_edge = (cx, cy)
                state.curr_edge = edges[0]
            cost -= self._cost(edges[0])
            start_node = edges[0].end
            edges.pop(0)
        if not self.params["prune_goal"] or not use_poses or not edges:
            return Route(start_node, edges, cost)
        prev, last = nodes[edges[-1].start], nodes[edges[-1].end]
        vpx, vpy = goal[0] - last.x, goal[1] - last.y
        cx, cy = closest_point(goal[0], goal[1], prev.x, prev.y, last.x, last.y)
        if (
            normalized_dot(last.x - prev.x, last.y - prev.y, vpx, vpy) < -_EPS
            and math.hypot(vpx, vpy) > float(self.params["min_prune_dist_from_goal"])
            and math.hypot(cx - goal[0], cy - goal[1]) <= float(self.params["max_prune_dist_from_edge"])
        ):
            cost -= self._cost(edges[-1])
            edges.pop()
        return Route(start_node, edges, cost)

    # --- path ------------------------------------------------------------------------------------------
    def densify(self, route: Route, state: ReroutingState | None = None) -> np.ndarray:
        """The route as an (N, 3) path every `path_density` metres, each pose heading along its edge."""
        density = float(self.params["path_density"])
        nodes = self.graph.nodes
        pts: list[tuple[float, float]] = []
        if state is not None and state.curr_edge is not None and state.closest_pt_on_edge is not None:
            end = nodes[state.curr_edge.end]
            pts.extend(_interpolate(*state.closest_pt_on_edge, end.x, end.y, density))
        if not route.edges:
            n = nodes[route.start_node]
            pts.append((n.x, n.y))
        else:
            for edge in route.edges:
                a, b = nodes[edge.start], nodes[edge.end]
                pts.extend(_interpolate(a.x, a.y, b.x, b.y, density))
            last = nodes[route.edges[-1].end]
            pts.append((last.x, last.y))
        xy = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        yaw = np.zeros(len(xy))
        if len(xy) > 1:
            d = np.diff(xy, axis=0)
            yaw[:-1] = np.arctan2(d[:, 1], d[:, 0])
            yaw[-1] = yaw[-2]
        if route.edges:
            a, b = nodes[route.edges[-1].start], nodes[route.edges[-1].end]
            yaw[-1] = math.atan2(b.y - a.y, b.x - a.x)
        return np.column_stack([xy, yaw])


def _interpolate(x0: float, y0: float, x1: float, y1: float, density: float) -> list[tuple[float, float]]:
    """Points from (x0, y0) towards (x1, y1) every <= density metres, the end point excluded."""
    mag = math.hypot(x1 - x0, y1 - y0)
    n = math.ceil(mag / density) if density > 0 else 1
    if n < 1:
        return []
    return [(x0 + (x1 - x0) * i / n, y0 + (y1 - y0) * i / n) for i in range(n)]


def line_blocked(costmap: Costmap2D, x0: float, y0: float, x1: float, y1: float, max_cost: float) -> bool:
    """Whether any cell along the straight line costs at least `max_cost` (unknown cells do not block)."""
    n = max(2, int(math.hypot(x1 - x0, y1 - y0) / costmap.resolution) + 1)
    pts = np.column_stack([np.linspace(x0, x1, n), np.linspace(y0, y1, n)])
    costs = costmap.costs_at(pts)
    return bool(np.any((costs >= max_cost) & (costs != NO_INFORMATION)))
