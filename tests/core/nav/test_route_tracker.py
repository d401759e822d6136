"""Route tracking: feedback on events only, node achievement (radius then bisector), completion, TF error,
and rerouting around an edge the local costmap shows blocked."""

from __future__ import annotations

import numpy as np
import pytest
from route_fixtures import edge, graph, node

from tb4.nav.costmap import LETHAL, Costmap2D
from tb4.nav.route_graph import parse_route_graph
from tb4.nav.route_planner import RoutePlanner, RouteRequest
from tb4.nav.route_tracker import RouteTrackingTask

pytestmark = pytest.mark.core


def two_way(i: int, a: int, b: int) -> list[dict]:
    return [edge(i, a, b), edge(i + 1, b, a)]


#  0 --- 1 --- 2
#  |           |
#  3 --------- 4
SQUARE = graph(
    node(0, 1, 5),
    node(1, 5, 5),
    node(2, 9, 5),
    node(3, 1, 1),
    node(4, 9, 1),
    *two_way(10, 0, 1),
    *two_way(12, 1, 2),
    *two_way(14, 0, 3),
    *two_way(16, 3, 4),
    *two_way(18, 2, 4),
)
FREE = Costmap2D(np.zeros((120, 200), dtype=np.uint8), 0.05, 0.0, 0.0)


def drive(task: RouteTrackingTask, path: np.ndarray, costmap: Costmap2D = FREE, t0: float = 0.0) -> list[dict]:
    """Move the 'robot' along `path` one pose per step, collecting the feedback events."""
    events = []
    t = t0
    for x, y, yaw in path[::4]:
        task.step((float(x), float(y), float(yaw)), lambda: costmap, t)
        t += 0.05
        while (fb := task.next_feedback()) is not None:
            events.append(fb)
        if task.done:
            break
    return events


def test_tracks_nodes_then_succeeds_with_event_feedback() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE))
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=2))
    task.step((0.2, 5.3, 0.0), lambda: FREE, 0.0)  # within boundary_radius_to_achieve_node of node 0
    first = task.next_feedback()
    assert first is not None and first["rerouted"] and first["next_node_id"] == 0 and first["current_edge_id"] == 0
    assert len(first["path"]) > 100 and first["route"].node_ids == [0, 1, 2]
    events = [fb for fb in iter(task.next_feedback, None)]
    task.step((0.25, 5.3, 0.0), lambda: FREE, 0.05)
    assert task.next_feedback() is None  # nothing new: no feedback
    events += drive(task, task.path, t0=0.1)
    assert task.status == "succeeded" and task.result()["error_code"] == 0
    passed = [(e["last_node_id"], e["current_edge_id"], e["next_node_id"]) for e in events]
    assert passed == [(0, 10, 1), (1, 12, 2), (2, 0, 0)]  # the last one: node 2 reached, no next node


def test_goal_succeeds_only_after_its_last_feedback_went_out() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE))
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=1))
    task.step((1.0, 5.0, 0.0), lambda: FREE, 0.0)
    task.step((5.0, 5.0, 0.0), lambda: FREE, 0.1)  # on node 1
    task.step((5.0, 5.0, 0.0), lambda: FREE, 0.2)
    assert not task.done  # feedback still queued
    events = list(iter(task.next_feedback, None))
    assert events[-1]["next_node_id"] == 0 and events[-1]["last_node_id"] == 1
    task.step((5.0, 5.0, 0.0), lambda: FREE, 0.3)
    assert task.status == "succeeded"
    assert task.result()["execution_duration"] > 0


def test_not_localized_is_tf_error_and_unknown_ids_fail() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE))
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=2))
    task.step(None, lambda: FREE, 0.0)
    assert task.status == "failed" and task.error_code == 401
    bad = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=77))
    bad.step((1.0, 5.0, 0.0), lambda: FREE, 0.0)
    assert bad.status == "failed" and bad.error_code == 400 and "77" in bad.error_msg


def test_blocked_edge_ahead_reroutes_from_the_last_node() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE))
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=3, goal_id=2))
    data = np.zeros((120, 200), dtype=np.uint8)
    task.step((1.0, 1.0, 0.0), lambda: Costmap2D(data, 0.05, 0.0, 0.0), 0.0)
    assert task.route is not None and task.route.node_ids == [3, 0, 1, 2]  # 12 m vs 12 m: either; the search picks this
    task.next_feedback()
    # drive past node 3 and node 0, then a pallet appears on edge 1 -> 2 (x 7, y 5)
    for i, (x, y) in enumerate([(1.0, 2.5), (1.0, 4.0), (1.0, 4.9), (2.0, 5.0), (3.0, 5.0)]):
        task.step((x, y, 0.0), lambda: Costmap2D(data, 0.05, 0.0, 0.0), 0.1 * (i + 1))
    data[95:105, 135:145] = LETHAL
    blocked = Costmap2D(data, 0.05, 0.0, 0.0)
    events = []
    for k in range(30):
        task.step((3.5, 5.0, 0.0), lambda: blocked, 1.0 + 0.05 * k)
        while (fb := task.next_feedback()) is not None:
            events.append(fb)
    rerouted = [e for e in events if e["rerouted"]]
    assert rerouted, events
    assert task.reroutes == 1  # blocked edge excluded from then on: no repeated reroutes
    route = rerouted[-1]["route"]
    assert route.node_ids[0] == 0 and route.node_ids[-1] == 2 and 12 not in [e.id for e in route.edges]
    assert all(not (e.start == 1 and e.end == 2) for e in route.edges)


def test_reroute_disabled_fails_with_operation_failed() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE), {"CollisionMonitor": {"reroute_on_collision": False}})
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=2))
    data = np.zeros((120, 200), dtype=np.uint8)
    data[95:105, 55:65] = LETHAL  # on edge 0 -> 1 at x 3
    task.step((1.0, 5.0, 0.0), lambda: FREE, 0.0)
    task.step((1.5, 5.0, 0.0), lambda: Costmap2D(data, 0.05, 0.0, 0.0), 2.0)
    task.step((1.6, 5.0, 0.0), lambda: Costmap2D(data, 0.05, 0.0, 0.0), 4.0)
    assert task.status == "failed" and task.error_code == 406


def test_rerouting_service_request_and_state_feedback() -> None:
    planner = RoutePlanner(parse_route_graph(SQUARE))
    task = RouteTrackingTask(planner, lambda pose: RouteRequest(start_id=0, goal_id=2))
    assert task.state_feedback() is None  # nothing planned yet
    task.step((1.0, 5.0, 0.0), lambda: FREE, 0.0)  # on node 0: edge 0 -> 1 entered
    list(iter(task.next_feedback, None))
    state = task.state_feedback()
    assert state is not None and not state["rerouted"] and state["current_edge_id"] == 10
    assert state["operations_triggered"] == ["ReroutingService", "CollisionMonitor"]
    first_route = task.route
    task.request_reroute()
    task.step((2.0, 5.0, 0.0), lambda: FREE, 0.05)
    events = list(iter(task.next_feedback, None))
    assert [e["rerouted"] for e in events] == [True] and task.route is not first_route
    assert task.reroutes == 1 and task.route.node_ids == [1, 2]  # from node 0, the edge the robot is on pruned
    assert task.path[0, 0] == pytest.approx(2.0) and task.path[0, 1] == pytest.approx(5.0)
