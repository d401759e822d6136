"""Route graph loading (Nav2 GeoJSON): malformed files fail with the file, the feature and a hint; shipped graphs
are drivable (every node free, every edge clear of walls and static obstacles, every node reachable)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from route_fixtures import edge, graph, node  # noqa: E402  (tests/core/nav on sys.path)

from tb4.config import ConfigError
from tb4.core.maps import OccupancyMap
from tb4.nav.costmap import INSCRIBED, GlobalCostmap
from tb4.nav.params import load_nav2_params
from tb4.nav.route_graph import load_route_graph, parse_route_graph
from tb4.sim.world import available_worlds, load_world
from tool_modules import load_tool

pytestmark = pytest.mark.core


GOOD = graph(node(0, 0, 0), node(1, 3, 4, metadata={"room": "a"}), edge(10, 0, 1, metadata={"speed_limit": 0.5}))


def test_parses_nodes_directed_edges_and_metadata() -> None:
    g = parse_route_graph(GOOD)
    assert set(g.nodes) == {0, 1} and g.nodes[1].metadata == {"room": "a"}
    assert [e.id for e in g.outgoing[0]] == [10] and g.outgoing[1] == []  # directed: no way back
    assert g.length(g.edges[10]) == pytest.approx(5.0)
    assert g.nearest_nodes(2.9, 3.8, 2) == [1, 0]


def test_upstream_sample_graph_features_are_accepted(tmp_path: Path) -> None:
    """The shape of nav2_route's sample_graph.geojson: frame, nested metadata, operations, non-overridable cost."""
    sample = graph(
        node(0, 0.0, 0.0, frame="map", operations={"stop": {"type": "stop", "trigger": "NODE", "metadata": {}}}),
        node(1, 1.0, 0.0, frame="map"),
        edge(9, 0, 1, overridable=False, cost=10.0, metadata={"speed_limit": 0.85, "aisle": {"n": 14}}),
    )
    sample["crs"] = {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}}
    path = tmp_path / "g.geojson"
    path.write_text(json.dumps(sample))
    g = load_route_graph(path)
    assert g.edges[9].cost == 10.0 and not g.edges[9].overridable


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("", "not valid JSON"),
        ("{", "not valid JSON"),
        ("[1, 2]", "FeatureCollection object"),
        ('{"features": 3}', "'features': expected a list"),
        ('{"feature": []}', "did you mean 'features'"),
        ('{"features": [{"geometry": {"type": "Point"}}]}', "'geometry' object and a 'properties' object"),
        (json.dumps(graph(node(0, 0, 0))), "at least one node and one edge"),
        (json.dumps(graph(node(0, 0, 0), node(0, 1, 1), edge(1, 0, 0))), "node id 0 is used twice"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 7))), "refers to node 7, which is not in"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 0))), "starts and ends at node 0"),
        (json.dumps(graph(node(-1, 0, 0), node(1, 1, 1), edge(1, 0, 1))), "integer id in 0..65535"),
        (json.dumps(graph(node(70000, 0, 0), node(1, 1, 1), edge(1, 70000, 1))), "integer id in 0..65535"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, startId=0))), "did you mean 'startid'"),
        ('{"features": [{"properties": {"id": 0}, "geometry": {"type": "Point", "coordinates": [NaN, 0]}}]}', "JSON"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1))).replace("[0, 0]", "[1e400, 0]", 1), "finite"),
        (json.dumps(graph(node(0, "a", 0), node(1, 1, 1), edge(1, 0, 1))), "finite number"),
        (json.dumps(graph(node(0, 0, 0, frame="odom"), node(1, 1, 1), edge(1, 0, 1))), "only the 'map' frame"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, cost=-2))), "must be >= 0"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, overridable=False))), "needs a cost > 0"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, overridable="no"))), "true or false"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, metadata={"speed_limit": 0}))), "> 0"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1, metadata=[1]))), "expected an object"),
        (json.dumps(graph(node(0, 0, 0), node(1, 1, 1), edge(1, 0, 1), edge(1, 1, 0))), "edge id 1 is used twice"),
        (
            json.dumps(
                graph(node(0, 0, 0, operations={"x": {"type": "t", "trigger": "SOON"}}), node(1, 1, 1), edge(1, 0, 1))
            ),
            "expected one of NODE",
        ),
        ('{"type": "Feature", "features": []}', "expected 'FeatureCollection'"),
        (json.dumps(graph({"type": "Feature", "properties": {"id": 0}, "geometry": {"type": "Polygon"}})), "Polygon"),
    ],
)
def test_malformed_graph_files_are_reported(tmp_path: Path, text: str, needle: str) -> None:
    path = tmp_path / "bad.geojson"
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        load_route_graph(path)
    assert needle in str(info.value) and str(path) in str(info.value)


def test_missing_and_unreadable_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="not found"):
        load_route_graph(tmp_path / "nope.geojson")
    binary = tmp_path / "bin.geojson"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ConfigError, match="cannot read|not valid JSON"):
        load_route_graph(binary)


@pytest.mark.parametrize("name", available_worlds())
def test_shipped_graphs_are_drivable(name: str) -> None:
    world = load_world(name)
    assert world.route_graph is not None and world.datum is not None
    g = load_route_graph(world.route_graph)
    data = world.map.data.copy()
    data[world.static_obstacle_mask() & (data >= 0)] = 100
    grid = OccupancyMap(
        data=data, resolution=world.map.resolution, origin_x=world.map.origin_x, origin_y=world.map.origin_y
    )
    costmap = GlobalCostmap(grid, load_nav2_params().costmap_params("global")).costmap
    for e in g.edges.values():
        a, b = g.nodes[e.start], g.nodes[e.end]
        pts = np.column_stack([np.linspace(a.x, b.x, 200), np.linspace(a.y, b.y, 200)])
        assert costmap.costs_at(pts).max() < INSCRIBED, f"{name}: edge {e.id} touches a wall or obstacle"
        assert any(r.start == e.end and r.end == e.start for r in g.outgoing[e.end]), f"edge {e.id} is one-way"
    # strongly connected (every edge has its reverse): one flood fill reaches every node
    seen, todo = {next(iter(g.nodes))}, [next(iter(g.nodes))]
    while todo:
        for e in g.outgoing[todo.pop()]:
            if e.end not in seen:
                seen.add(e.end)
                todo.append(e.end)
    assert seen == set(g.nodes)
    assert 1 in g.nodes  # the dock's staging spot is a node in every world
    for dest in world.destinations.values():  # every named place is a short drive from a node
        near = g.nodes[g.nearest_nodes(dest.x, dest.y)[0]]
        assert np.hypot(near.x - dest.x, near.y - dest.y) < 2.5, (name, dest.name)


def test_world_keys_are_validated(tmp_path: Path) -> None:
    src = load_world("depot").source.read_text()
    bad = tmp_path / "w.yaml"
    bad.write_text(
        src.replace("datum: [", "datum: [95.0, ")
        .replace("depot_map.yaml", str(load_world("depot").map_path))
        .replace("depot_graph.geojson", "missing.geojson")
    )
    with pytest.raises(ConfigError):
        load_world(bad)
    bad.write_text(
        src.replace("depot_map.yaml", str(load_world("depot").map_path)).replace(
            "depot_graph.geojson", "missing.geojson"
        )
    )
    with pytest.raises(ConfigError, match="route graph file not found"):
        load_world(bad)
    bad.write_text(
        src.replace("depot_map.yaml", str(load_world("depot").map_path)).replace("route_graph:", "route_grap:")
    )
    with pytest.raises(ConfigError, match="did you mean 'route_graph'"):
        load_world(bad)


def test_committed_graphs_match_the_drawing_tool() -> None:
    module = load_tool("draw_route_graphs")
    assert module.main(["--check"]) == 0
