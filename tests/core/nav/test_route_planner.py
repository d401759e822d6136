"""Route planning: Dijkstra optimality against scipy, Nav2's edge costs (length / speed_limit, penalty,
non-overridable cost), blocked edges, start/goal by id or pose (nearest visible node), pruning, the dense path
and every error code."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from route_fixtures import edge, graph, node
from scipy.sparse.csgraph import dijkstra

from tb4.nav.costmap import LETHAL, Costmap2D
from tb4.nav.route_graph import parse_route_graph
from tb4.nav.route_planner import ReroutingState, RouteError, RoutePlanner, RouteRequest
from tb4.sim.world import load_world

pytestmark = pytest.mark.core


def two_way(i: int, a: int, b: int, **props: object) -> list[dict]:
    return [edge(i, a, b, **props), edge(i + 1, b, a, **props)]


#  0 ---- 1 ---- 2        a square with a diagonal shortcut whose speed limit makes it slow
#  |             |
#  3 ----------- 4
SQUARE = graph(
    node(0, 0, 4),
    node(1, 4, 4),
    node(2, 8, 4),
    node(3, 0, 0),
    node(4, 8, 0),
    *two_way(10, 0, 1),
    *two_way(12, 1, 2),
    *two_way(14, 0, 3),
    *two_way(16, 3, 4),
    *two_way(18, 2, 4),
    *two_way(20, 0, 4, metadata={"speed_limit": 0.5}),
)


def planner(g: dict = SQUARE, **params: object) -> RoutePlanner:
    return RoutePlanner(parse_route_graph(g), params)


def test_edge_costs_follow_nav2_scorers() -> None:
    p = planner()
    e = p.graph.edges
    assert p.edge_cost(e[10]) == pytest.approx(4.0)
    assert p.edge_cost(e[20]) == pytest.approx(math.hypot(8, 4) / 0.5)  # DistanceScorer: length / speed_limit
    pen = planner(graph(node(0, 0, 0), node(1, 3, 0), edge(1, 0, 1, metadata={"penalty": 2.5})))
    assert pen.edge_cost(pen.graph.edges[1]) == pytest.approx(5.5)
    fixed = planner(graph(node(0, 0, 0), node(1, 3, 0), edge(1, 0, 1, cost=42.0, overridable=False)))
    assert fixed.edge_cost(fixed.graph.edges[1]) == 42.0
    weighted = planner(PenaltyScorer={"weight": 10.0})
    assert weighted.params["DistanceScorer"]["weight"] == 1.0  # nested defaults kept


def test_search_matches_reference_dijkstra_on_random_graphs() -> None:
    rng = np.random.default_rng(3)
    for trial in range(20):
        n = 30
        xy = rng.uniform(0, 50, size=(n, 2))
        feats = [node(i, *xy[i]) for i in range(n)]
        pairs = {(int(a), int(b)) for a, b in rng.integers(0, n, size=(90, 2)) if a != b}
        for k, (a, b) in enumerate(sorted(pairs)):
            feats.append(edge(1000 + k, a, b, metadata={"penalty": float(rng.uniform(0, 3))}))
        p = planner(graph(*feats))
        matrix = sp.lil_matrix((n, n))
        for e in p.graph.edges.values():
            matrix[e.start, e.end] = p.edge_cost(e)
        dist = dijkstra(matrix.tocsr(), directed=True, indices=0)
        for goal in range(1, n):
            if math.isinf(dist[goal]):
                with pytest.raises(RouteError) as info:
                    p.search(0, goal)
                assert info.value.code == 405
                continue
            route = p.search(0, goal)
            assert route.cost == pytest.approx(dist[goal], rel=1e-9), (trial, goal)
            assert sum(p.edge_cost(e) for e in route.edges) == pytest.approx(route.cost)
            assert route.node_ids[0] == 0 and route.node_ids[-1] == goal
            assert all(a.end == b.start for a, b in zip(route.edges, route.edges[1:], strict=False))


def test_slow_shortcut_is_avoided_and_blocked_edges_reroute() -> None:
    p = planner()
    assert p.search(0, 4).node_ids == [0, 3, 4]  # 12 m beats the 8.9 m diagonal at half speed (17.9)
    assert p.search(0, 4, blocked=[16]).node_ids == [0, 1, 2, 4]  # edge 16 (3 -> 4) blocked
    assert p.search(0, 4, blocked=[3, 1]).node_ids == [0, 4]  # nodes blocked: only the diagonal is left
    with pytest.raises(RouteError) as info:
        p.search(0, 4, blocked=[3, 1, 20])
    assert info.value.code == 405 and "route from node 0 to node 4" in str(info.value)
    assert p.search(2, 2).edges == []


def test_dynamic_edges_close_reopen_and_recost() -> None:
    p = planner()
    p.adjust_edges(closed=[16], opened=[], costs={})
    assert p.search(0, 4).node_ids == [0, 1, 2, 4]  # 3 -> 4 closed
    p.adjust_edges(closed=[], opened=[16], costs={14: 100.0})  # reopened, but 0 -> 3 now costs 104
    assert p.search(0, 4).node_ids == [0, 1, 2, 4]
    p.adjust_edges(closed=[], opened=[], costs={14: 0.0})
    assert p.search(0, 4).node_ids == [0, 3, 4]
    with pytest.raises(ValueError):
        p.adjust_edges(closed=[10], opened=[], costs={12: math.nan})
    assert 10 not in p.closed_edges  # all or nothing
    fixed = planner(graph(node(0, 0, 0), node(1, 3, 0), edge(1, 0, 1, cost=42.0, overridable=False)))
    fixed.adjust_edges(closed=[1], opened=[], costs={})
    assert fixed.search(0, 1).cost == 42.0  # not overridable: the scorers (closing included) do not apply


def test_start_and_goal_by_id_and_by_pose() -> None:
    p = planner()
    route = p.find_route(RouteRequest(start_id=3, goal_id=1))
    assert route.node_ids == [3, 0, 1] and route.cost == pytest.approx(8.0)
    with pytest.raises(RouteError) as info:
        p.find_route(RouteRequest(start_id=3, goal_id=99))
    assert info.value.code == 400 and "goal node id 99 is not in the route graph" in str(info.value)
    # poses: nearest nodes 0 and 4; the goal lies along the last edge (3 -> 4) short of node 4: that edge goes
    route = p.find_route(RouteRequest(start=(0.2, 4.1, 0.0), goal=(7.9, 0.3, 0.0), use_poses=True))
    assert route.node_ids == [0, 3]
    route = p.find_route(RouteRequest(start=(0.0, 4.0, 0.0), goal=(8.0, -0.3, 0.0), use_poses=True))
    assert route.node_ids == [0, 3, 4]  # beyond node 4: kept
    route = p.find_route(RouteRequest(start=(1.5, 4.0, 0.0), goal=(8.0, 4.0, 0.0), use_poses=True))
    assert route.node_ids == [1, 2]  # nearest start node 1 ... no pruning needed
    # start at x 1.0 on edge 0 -> 1 (nearest node 0): the route 0 -> 1 -> 2 loses its first edge
    route = p.find_route(RouteRequest(start=(1.0, 4.0, 0.0), goal=(8.0, 4.0, 0.0), use_poses=True))
    assert route.node_ids == [1, 2] and route.cost == pytest.approx(4.0)
    for bad in [(math.nan, 0.0, 0.0), (math.inf, 1.0, 0.0)]:
        with pytest.raises(RouteError) as info:
            p.find_route(RouteRequest(start=(0.0, 0.0, 0.0), goal=bad, use_poses=True))
        assert info.value.code == 403
    with pytest.raises(RouteError) as info:
        p.find_route(RouteRequest(start=None, goal=(1.0, 1.0, 0.0), use_poses=True))
    assert info.value.code == 401


def test_pruning_of_start_and_goal_edges() -> None:
    line = graph(node(0, 0, 0), node(1, 5, 0), node(2, 10, 0), *two_way(1, 0, 1), *two_way(3, 1, 2))
    p = planner(line)
    # robot at x 1, past node 0 along the first edge: that edge is pruned
    route = p.find_route(RouteRequest(start=(1.0, 0.0, 0.0), goal=(10.0, 0.0, 0.0), use_poses=True))
    assert route.node_ids == [1, 2]
    route = p.find_route(RouteRequest(start=(0.0, 0.0, 0.0), goal=(9.0, 0.0, 0.0), use_poses=True))
    assert route.node_ids == [0, 1]  # goal short of node 2 along the last edge: the path ends at node 1
    route = p.find_route(RouteRequest(start=(0.0, 0.0, 0.0), goal=(6.0, 0.0, 0.0), use_poses=True))
    assert route.node_ids == [0, 1]  # nearest goal node is 1
    no_prune = planner(line, prune_goal=False)
    assert no_prune.find_route(RouteRequest(start=(0.05, 0.0, 0.0), goal=(10, 0, 0), use_poses=True)).node_ids == [
        0,
        1,
        2,
    ]
    # ids never prune on the first request
    assert p.find_route(RouteRequest(start_id=0, goal_id=2)).node_ids == [0, 1, 2]


def test_nearest_node_search_skips_nodes_behind_a_wall() -> None:
    g = graph(node(0, 1.0, 1.0), node(1, 3.0, 1.0), *two_way(1, 0, 1))
    data = np.zeros((60, 100), dtype=np.uint8)
    data[:, 38:42] = LETHAL  # a wall at x 1.9 .. 2.1 (0.05 m cells from x 0)
    costmap = Costmap2D(data, 0.05, 0.0, 0.0)
    p = planner(g)
    start = (2.3, 1.0, 0.0)  # nearer to node 0 through the wall, but sees node 1
    assert p.find_start_and_goal(RouteRequest(start=(1.9, 1.0, 0.0), goal=(3.0, 1.0, 0.0), use_poses=True)) == (0, 1)
    assert p.find_start_and_goal(RouteRequest(start=start, goal=(3, 1, 0), use_poses=True), costmap)[0] == 1
    assert (
        planner(g, enable_nn_search=False).find_start_and_goal(
            RouteRequest(start=(1.9, 1.0, 0.0), goal=(3, 1, 0), use_poses=True), costmap
        )[0]
        == 0
    )
    with pytest.raises(RouteError) as info:
        p.find_start_and_goal(RouteRequest(start=start, goal=(30.0, 1.0, 0.0), use_poses=True), costmap)
    assert info.value.code == 403 and "outside the map" in str(info.value)


def test_max_iterations_is_nav2_timeout() -> None:
    p = planner(max_iterations=2)
    with pytest.raises(RouteError) as info:
        p.search(0, 2)
    assert info.value.code == 404


def test_dense_path_every_density_with_edge_headings() -> None:
    p = planner()
    route = p.find_route(RouteRequest(start_id=0, goal_id=2))
    path = p.densify(route)
    steps = np.hypot(*np.diff(path[:, :2], axis=0).T)
    assert steps.max() <= 0.05 + 1e-9 and path.shape[1] == 3
    assert tuple(path[0, :2]) == (0.0, 4.0) and tuple(path[-1, :2]) == (8.0, 4.0)
    assert np.allclose(path[:, 2], 0.0)
    # rerouted along the same edge: the path starts at the robot's closest point on it
    state = ReroutingState(curr_edge=p.graph.edges[10], closest_pt_on_edge=(2.0, 4.0))
    rest = p.densify(p.search(1, 2), state)
    assert tuple(rest[0, :2]) == (2.0, 4.0) and tuple(rest[-1, :2]) == (8.0, 4.0)
    single = p.densify(p.search(3, 3))
    assert single.shape == (1, 3)


def test_shipped_warehouse_forklift_aisle_penalty_diverts_routes_when_weighted() -> None:
    from tb4.nav.route_graph import load_route_graph

    world = load_world("warehouse")
    assert world.route_graph is not None
    graph_ = load_route_graph(world.route_graph)
    direct = RoutePlanner(graph_).find_route(RouteRequest(start_id=1, goal_id=21))
    assert direct.node_ids == [1, 43, 32, 11, 21]  # the 2.0 penalty is less than the detour
    detour = RoutePlanner(graph_, {"PenaltyScorer": {"weight": 10.0}}).find_route(RouteRequest(start_id=1, goal_id=21))
    assert not any(e.start == 32 and e.end == 11 for e in detour.edges) and detour.node_ids[-1] == 21
    assert detour.cost < direct.cost + 18.0  # and it is the cheapest under the new weights
    # by pose: the loading bay has its own node on the south aisle
    by_pose = RoutePlanner(graph_).find_route(
        RouteRequest(start=(-0.7, 0.0, 0.0), goal=(2.0, -23.0, 0.0), use_poses=True)
    )
    assert by_pose.node_ids[0] == 1 and by_pose.node_ids[-2:] == [21, 24]
    # a goal a little short of node 24 along the aisle from 21: Nav2's goal pruning drops the last edge
    short = RoutePlanner(graph_).find_route(
        RouteRequest(start=(-0.7, 0.0, 0.0), goal=(1.5, -23.1, 0.0), use_poses=True)
    )
    assert short.node_ids[-1] == 21
