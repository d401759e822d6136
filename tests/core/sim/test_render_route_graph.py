"""`tb4 render` draws the world's route graph: teal edges and nodes appear only when a graph is given."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tb4.nav.route_graph import load_route_graph
from tb4.sim.render import render_world
from tb4.sim.world import load_world

pytestmark = pytest.mark.core

TEAL = np.array([0x26, 0xA6, 0x9A])


def _teal(path: Path) -> int:
    with Image.open(path) as img:
        pixels = np.asarray(img.convert("RGB")).astype(int)
    return int((np.abs(pixels - TEAL).max(axis=2) <= 40).sum())


@pytest.mark.parametrize("name", ["warehouse", "depot", "maze"])
def test_route_graph_is_drawn(tmp_path: Path, name: str) -> None:
    world = load_world(name)
    assert world.route_graph is not None
    bare = render_world(world, tmp_path / "bare.png")
    with_graph = render_world(world, tmp_path / "graph.png", route_graph=load_route_graph(world.route_graph))
    assert _teal(bare) < 20 and _teal(with_graph) > 100
