"""ComputeAndTrackRoute as a step-able task: plan a route, then follow the robot along it, rerouting on blockage.

Like Nav2's route server, tracking does not drive: the client follows `feedback.path` (with FollowPath or a
navigator) and this task watches the localized pose. A node counts as achieved when the robot comes within
`radius_to_achieve_node` (`boundary_radius_to_achieve_node` for the route's first and last nodes) and then
crosses the bisector of the edges meeting there (or leaves the radius again). Feedback is sent on events only:
a new route (`rerouted` true, the first one too), a node passed, the last node reached (next node and edge 0);
the goal succeeds once that last feedback has gone out. The CollisionMonitor operation checks the
local costmap along the route ahead (up to `max_collision_dist`, at `rate` Hz of sim time); a blocked edge is
excluded and the route recomputed from the last node passed.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from tb4.core.geometry import Pose
from tb4.nav.costmap import Costmap2D
from tb4.nav.route_graph import RouteEdge
from tb4.nav.route_planner import (
    ReroutingState,
    Route,
    RouteError,
    RoutePlanner,
    RouteRequest,
    closest_point,
    line_blocked,
    normalized_dot,
)
from tb4.nav.tasks import CANCELED, FAILED, RUNNING, SUCCEEDED, TERMINAL

__all__ = ["RouteTrackingTask", "QUERY_OPERATIONS"]

# Route operations run on every tracking cycle (Nav2's query operations); their names go in operations_triggered
QUERY_OPERATIONS = ("ReroutingService", "CollisionMonitor")


class _TrackingState:
    def __init__(self, route: Route) -> None:
        self.next_node: int | None = route.start_node
        self.last_node: int | None = None
        self.current_edge: RouteEdge | None = None
        self.edge_index = -1
        self.within_radius = False


class RouteTrackingTask:
    """One ComputeAndTrackRoute goal. `request_fn(pose)` builds the RouteRequest from the current robot pose."""

    name = "compute_and_track_route"

    def __init__(self, planner: RoutePlanner, request_fn: Callable[[Pose | None], RouteRequest]) -> None:
        self.planner = planner
        self.request_fn = request_fn
        self.params = planner.params
        self.status = RUNNING
        self.error_code = 0
        self.error_msg = ""
        self.start_time: float | None = None
        self.end_time: float | None = None
        self.route: Route | None = None
        self.path: np.ndarray = np.zeros((0, 3))
        self.reroutes = 0
        self._rerouting = ReroutingState()
        self._state: _TrackingState | None = None
        self._events: deque[dict[str, Any]] = deque()
        self._last_check = -math.inf
        self._arrived: float | None = None  # sim time the last node was reached; done once its feedback went out
        self._reroute_requested = False

    # --- task protocol ---------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self.status in TERMINAL

    def cancel(self) -> None:
        if not self.done:
            self.status = CANCELED

    def next_feedback(self) -> dict[str, Any] | None:
        """The oldest feedback event not yet sent (None when there is none): feedback is event-driven."""
        return self._events.popleft() if self._events else None

    def feedback(self) -> dict[str, Any]:
        return self._events[0] if self._events else {}

    def state_feedback(self) -> dict[str, Any] | None:
        """The current tracking state as a feedback (what Nav2 sends every cycle while its query operations run)."""
        state = self._state
        if self.route is None or state is None or state.current_edge is None or self._arrived is not None:
            return None
        return {
            "rerouted": False,
            "next_node_id": int(state.next_node or 0),
            "last_node_id": int(state.last_node or 0),
            "current_edge_id": int(state.current_edge.id),
            "route": self.route,
            "path": self.path,
            "operations_triggered": list(QUERY_OPERATIONS),
        }

    def request_reroute(self) -> None:
        """ReroutingService: recompute the route from the last node passed on the next cycle."""
        self._reroute_requested = True

    def result(self) -> dict[str, Any]:
        duration = 0.0 if self.start_time is None else max(0.0, (self.end_time or self.start_time) - self.start_time)
        return {"execution_duration": duration, "error_code": self.error_code, "error_msg": self.error_msg}

    # --- stepping --------------------------------------------------------------------------------------
    def step(
        self,
        pose: Pose | None,
        costmap_fn: Callable[[], Costmap2D | None],
        now: float,
        planning_costmap_fn: Callable[[], Costmap2D | None] | None = None,
    ) -> str:
        """One cycle. `costmap_fn` gives the local costmap (the collision check ahead); `planning_costmap_fn`
        the whole-map one the start and goal poses are snapped to nodes on (default: the local one)."""
        if self.done:
            return self.status
        if self.start_time is None:
            self.start_time = now
        try:
            self._step(pose, costmap_fn, now, planning_costmap_fn or costmap_fn)
        except RouteError as exc:
            self._finish(FAILED, now, exc.code, str(exc))
        except Exception as exc:  # a bug must not kill the loop: fail this goal with the reason
            self._finish(FAILED, now, 400, f"internal error in route tracking: {type(exc).__name__}: {exc}")
        return self.status

    def _finish(self, status: str, now: float, code: int = 0, msg: str = "") -> None:
        self.status, self.error_code, self.error_msg, self.end_time = status, code, msg, now

    def _plan(self, pose: Pose | None, costmap: Costmap2D | None) -> None:
        request = self.request_fn(pose)
        self.route = self.planner.find_route(request, self._rerouting, costmap)
        self.path = self.planner.densify(self.route, self._rerouting)
        state = _TrackingState(self.route)
        curr = self._rerouting.curr_edge
        if curr is not None:  # still on the edge we were on: keep it as the current one
            state.current_edge, state.last_node = curr, curr.start
        self._state = state
        self._emit(True, self.route.start_node, state.last_node or 0, curr.id if curr else 0)

    def _emit(
        self, rerouted: bool, next_node: int, last_node: int, edge: int, operations: tuple[str, ...] = ()
    ) -> None:
        assert self.route is not None
        self._events.append(
            {
                "rerouted": rerouted,
                "next_node_id": int(next_node),
                "last_node_id": int(last_node),
                "current_edge_id": int(edge),
                "route": self.route,
                "path": self.path,
                "operations_triggered": list(operations),
            }
        )

    def _step(
        self,
        pose: Pose | None,
        costmap_fn: Callable[[], Costmap2D | None],
        now: float,
        planning_costmap_fn: Callable[[], Costmap2D | None],
    ) -> None:
        if self._arrived is not None:
            if not self._events:  # the final feedback (last node reached) has been sent: the goal succeeds
                self._finish(SUCCEEDED, self._arrived)
            return
        if pose is None:
            raise RouteError("TF_ERROR", "unable to get the robot pose in the map frame: set an initial pose first")
        if self._state is None:
            self._plan(pose, planning_costmap_fn())
        state, route = self._state, self.route
        assert state is not None and route is not None
        if self._node_achieved(pose, state, route):
            state.within_radius = False
            state.last_node = state.next_node
            state.edge_index += 1
            if state.edge_index < len(route.edges):
                state.current_edge = route.edges[state.edge_index]
                state.next_node = state.current_edge.end
                self._emit(False, state.next_node, state.last_node or 0, state.current_edge.id)
            else:  # like Nav2, a last feedback: no next node, no current edge, the last node reached
                self._emit(False, 0, state.last_node or 0, 0)
                self._arrived = now
                return
        blocked = self._collision_check(pose, state, route, costmap_fn, now)
        requested, self._reroute_requested = self._reroute_requested, False
        if blocked is not None or requested:
            info = self._rerouting
            new = [blocked] if blocked is not None else []
            info.blocked_ids = info.blocked_ids + new if self.params["aggregate_blocked_ids"] else new
            info.rerouting_start_id = state.last_node
            info.rerouting_start_pose = pose if state.last_node is not None else None
            info.curr_edge = state.current_edge
            self.reroutes += 1
            self._plan(pose, planning_costmap_fn())

    def _node_achieved(self, pose: Pose, state: _TrackingState, route: Route) -> bool:
        nodes = self.planner.graph.nodes
        if state.next_node is None:
            return False
        nxt = nodes[state.next_node]
        dx, dy = nxt.x - pose[0], nxt.y - pose[1]
        dist = math.hypot(dx, dy)
        boundary = state.edge_index == len(route.edges) - 1 or (state.edge_index == -1 and state.current_edge is None)
        radius = float(self.params["boundary_radius_to_achieve_node" if boundary else "radius_to_achieve_node"])
        in_radius = dist <= radius
        if dist < 1e-4 or (not in_radius and state.within_radius):
            return True
        state.within_radius = in_radius
        if boundary:
            return state.within_radius
        if state.within_radius and state.current_edge is not None:
            last = nodes[state.current_edge.start]
            future = nodes[route.edges[state.edge_index + 1].end]
            nx_, ny_ = nxt.x - last.x, nxt.y - last.y
            mx, my = future.x - nxt.x, future.y - nxt.y
            n_mag, m_mag = math.hypot(nx_, ny_), math.hypot(mx, my)
            if n_mag < 1e-6 or m_mag < 1e-6:
                return True
            return normalized_dot(nx_ * m_mag + mx * n_mag, ny_ * m_mag + my * n_mag, dx, dy) <= 0.0
        return False

    def _collision_check(
        self,
        pose: Pose,
        state: _TrackingState,
        route: Route,
        costmap_fn: Callable[[], Costmap2D | None],
        now: float,
    ) -> int | None:
        """The id of the first blocked edge within max_collision_dist ahead, or None (CollisionMonitor)."""
        cm = self.params["CollisionMonitor"]
        rate = float(cm["rate"])
        edge = state.current_edge
        if edge is None or (rate > 0 and now - self._last_check < 1.0 / rate):
            return None
        self._last_check = now
        costmap = costmap_fn()
        if costmap is None:
            raise RouteError("OPERATION_FAILED", "CollisionMonitor could not obtain the local costmap")
        nodes = self.planner.graph.nodes
        max_dist = float(cm["max_collision_dist"]) if float(cm["max_collision_dist"]) > 0 else math.inf
        a, b = nodes[edge.start], nodes[edge.end]
        sx, sy = closest_point(pose[0], pose[1], a.x, a.y, b.x, b.y)
        checked = 0.0
        index = state.edge_index
        while True:
            end = nodes[edge.end]
            ex, ey = end.x, end.y
            length = math.hypot(ex - sx, ey - sy)
            last = checked + length >= max_dist
            if last and length > 0:
                frac = (max_dist - checked) / length
                ex, ey = sx + (ex - sx) * frac, sy + (ey - sy) * frac
            checked += length
            if line_blocked(costmap, sx, sy, ex, ey, float(cm["max_cost"])):
                if not cm["reroute_on_collision"]:
                    raise RouteError("OPERATION_FAILED", "collision detected ahead and reroute_on_collision is off")
                return edge.id
            index += 1
            if last or index >= len(route.edges) or index < 0:
                return None
            edge = route.edges[index]
            sx, sy = ex, ey
