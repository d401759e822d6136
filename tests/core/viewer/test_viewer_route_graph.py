"""The viewer's world description carries the route graph, so the page can draw it (and copes without one)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tb4.sim.world import load_world
from tb4.viewer.world_info import world_info

pytestmark = pytest.mark.core


def test_world_info_has_the_route_graph() -> None:
    info = world_info(load_world("maze"))
    graph = info["route_graph"]
    assert len(graph["nodes"]) == 121 and all(len(n) == 3 for n in graph["nodes"])
    assert len(graph["edges"]) == 132 and all(len(e) == 4 for e in graph["edges"])  # two-way pairs drawn once
    json.dumps(info)  # goes to the page as JSON


def test_missing_or_broken_graph_is_left_out(tmp_path: Path) -> None:
    world = load_world("depot")
    world.route_graph = None
    assert world_info(world)["route_graph"] is None
    broken = tmp_path / "g.geojson"
    broken.write_text("{")
    world.route_graph = broken
    assert world_info(world)["route_graph"] is None


def test_a_hostile_world_reference_gives_no_world_and_a_reason(tmp_path) -> None:
    """The `world` topic is a string anyone on the domain can publish: no reference may hang or crash the viewer."""
    from tb4.viewer.world_info import WorldInfoCache

    cache = WorldInfoCache()
    for reference in ("/dev/zero", str(tmp_path), "/etc/passwd", "no_such_world", "x" * 10_000 + ".yaml"):
        assert cache.get(reference) is None
        assert cache.errors[reference]
