#!/usr/bin/env python3
"""Draw the route graphs of our shipped worlds and write them in Nav2 route server's GeoJSON format.

``python tools/draw_route_graphs.py`` rewrites ``src/tb4/worlds/<name>_graph.geojson``; ``--check`` only
compares with the committed files (exit 1 if they differ). Warehouse and depot graphs follow their aisles by
hand; the maze graph joins the centres of neighbouring corridor cells the robot can drive between. Every edge
is two-way (two directed edges, ids 1000+), and every edge is checked to keep the robot clear of the map's walls
and the world's static obstacles.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from tb4.core.maps import OccupancyMap  # noqa: E402
from tb4.nav.costmap import GlobalCostmap  # noqa: E402
from tb4.nav.params import load_nav2_params  # noqa: E402
from tb4.sim.world import WORLDS_DIR, load_world  # noqa: E402

MAX_EDGE_COST = 180  # costmap cost an edge may touch: about 0.3 m of clearance around the robot

Nodes = dict[int, tuple[float, float]]
Links = list[tuple[int, int]]


def _chain(ids: list[int]) -> Links:
    return list(zip(ids, ids[1:], strict=False))


def warehouse() -> tuple[Nodes, Links, dict[tuple[int, int], dict]]:
    nodes: Nodes = {}
    links: Links = []
    meta: dict[tuple[int, int], dict] = {}
    # south: the cross aisle between the rack blocks (y -15.25) and the one along the south wall (y -23.1)
    aisles = [-8.6, -1.4, 5.8, 13.0]
    for i, x in enumerate(aisles):
        nodes[10 + i] = (x, -15.25)
        nodes[20 + i] = (x, -23.1)
        links.append((10 + i, 20 + i))
    links += _chain([10, 11, 12, 13]) + [(20, 21), (22, 23)]  # 21 - 22 runs through the loading bay (24)
    # the floor: a row along the south racks, then three rows between the pillars
    nodes[31], nodes[32], nodes[33] = (-8.6, -7.6), (-1.4, -7.6), (5.8, -7.6)
    links += _chain([31, 32, 33]) + [(31, 10), (32, 11), (33, 12)]  # down the rack aisles
    xs = [-12.0, -9.6, -5.0, -1.4, 7.0, 12.0]
    for base, y in ((40, -3.6), (50, 2.5), (60, 10.0)):
        for i, x in enumerate(xs):
            nodes[base + i] = (x, y)
        links += _chain([base + i for i in range(len(xs))])
    for i in range(len(xs)):
        links += [(40 + i, 50 + i), (50 + i, 60 + i)]
    links += [(31, 41), (32, 43), (33, 44)]
    # the aisle at x -1.4 carries a forklift: make it a little less attractive than the parallel ones
    meta[(32, 11)] = {"penalty": 2.0}
    # north: the gap between the rack columns (x -5.0) and the open side by the office (x 5.5)
    nodes[70], nodes[71], nodes[72] = (-5.0, 13.85), (-5.0, 17.35), (-5.0, 20.85)
    nodes[73], nodes[74] = (5.5, 13.85), (5.5, 17.35)
    nodes[75] = (9.6, 15.3)  # before the office door
    nodes[76] = (-12.0, 13.85)
    links += [(62, 70), (70, 71), (71, 72), (64, 73), (73, 74), (73, 75), (70, 73), (76, 70), (71, 74)]
    # the dock: its staging spot, 0.7 m in front of the docked pose
    nodes[1] = (-0.7, 0.0)
    links += [(1, 53), (1, 43)]
    nodes[24] = (2.0, -23.1)  # the loading bay
    links += [(21, 24), (24, 22)]
    return nodes, links, meta


def depot() -> tuple[Nodes, Links, dict[tuple[int, int], dict]]:
    nodes: Nodes = {
        1: (-0.7, 0.0),
        10: (-12.0, 5.3),
        11: (-6.0, 5.3),
        12: (-1.5, 5.3),
        13: (5.0, 5.3),
        14: (9.3, 5.3),
        20: (-12.0, -1.5),
        21: (-6.0, -1.5),
        22: (-1.5, -1.5),
        23: (3.0, -1.8),
        24: (9.3, -1.8),
        25: (13.0, -1.5),
        30: (-5.5, -6.0),
        31: (2.0, -5.5),
        32: (7.5, -5.0),
        15: (1.5, 1.5),  # by the barrels and the crate
    }
    links: Links = _chain([10, 11, 12, 13, 14]) + _chain([20, 21, 22, 23, 24, 25]) + _chain([30, 31, 32])
    links += [(10, 20), (11, 21), (12, 22), (14, 24), (21, 30), (22, 31), (1, 22), (15, 1), (15, 23)]
    return nodes, links, {}


def maze() -> tuple[Nodes, Links, dict[tuple[int, int], dict]]:
    world = load_world("maze")
    costmap = _costmap(world)
    centres = [round(-9.0 + 1.8 * i, 2) for i in range(11)]
    nodes: Nodes = {}
    index = {}
    for r, y in enumerate(centres):
        for c, x in enumerate(centres):
            if costmap.cost_at(x, y) <= MAX_EDGE_COST:
                node_id = 100 + r * 11 + c
                nodes[node_id] = (x, y)
                index[(r, c)] = node_id
    links: Links = []
    for (r, c), a in index.items():
        for dr, dc in ((0, 1), (1, 0)):
            b = index.get((r + dr, c + dc))
            if b is not None and _clear(costmap, nodes[a], nodes[b]):
                links.append((a, b))
    nodes[1] = (-0.7, 0.0)
    links.append((1, index[(5, 4)]))
    return nodes, links, {}


DRAWERS = {"warehouse": warehouse, "depot": depot, "maze": maze}


def _costmap(world):  # type: ignore[no-untyped-def]
    grid = world.map
    data = grid.data.copy()
    data[world.static_obstacle_mask() & (data >= 0)] = 100
    masked = OccupancyMap(data=data, resolution=grid.resolution, origin_x=grid.origin_x, origin_y=grid.origin_y)
    return GlobalCostmap(masked, load_nav2_params().costmap_params("global")).costmap


def _clear(costmap, a: tuple[float, float], b: tuple[float, float]) -> bool:  # type: ignore[no-untyped-def]
    n = max(2, int(np.hypot(b[0] - a[0], b[1] - a[1]) / 0.02))
    pts = np.column_stack([np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n)])
    return bool(np.all(costmap.costs_at(pts) <= MAX_EDGE_COST))


def build(name: str) -> dict:
    nodes, links, meta = DRAWERS[name]()
    world = load_world(name)
    costmap = _costmap(world)
    bad = [(a, b) for a, b in links if not _clear(costmap, nodes[a], nodes[b])]
    if bad:
        raise SystemExit(f"{name}: edges too close to walls or obstacles: {bad}")
    features = [
        {
            "type": "Feature",
            "properties": {"id": nid, "frame": "map"},
            "geometry": {"type": "Point", "coordinates": [x, y]},
        }
        for nid, (x, y) in sorted(nodes.items())
    ]
    edge_id = 1000
    for a, b in links:
        for s, e in ((a, b), (b, a)):
            props: dict = {"id": edge_id, "startid": s, "endid": e}
            extra = meta.get((a, b))
            if extra:
                props["metadata"] = dict(extra)
            features.append(
                {
                    "type": "Feature",
                    "properties": props,
                    "geometry": {"type": "MultiLineString", "coordinates": [[list(nodes[s]), list(nodes[e])]]},
                }
            )
            edge_id += 1
    return {"type": "FeatureCollection", "name": f"{name}_graph", "features": features}


def render(graph: dict) -> str:
    lines = ",\n".join("    " + json.dumps(f) for f in graph["features"])
    return f'{{\n  "type": "FeatureCollection",\n  "name": "{graph["name"]}",\n  "features": [\n{lines}\n  ]\n}}\n'


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="compare with the committed files only")
    args = parser.parse_args(argv)
    status = 0
    for name in DRAWERS:
        text = render(build(name))
        path = WORLDS_DIR / f"{name}_graph.geojson"
        if args.check:
            if not path.is_file() or path.read_text() != text:
                print(f"{path} differs from the drawing")
                status = 1
        else:
            path.write_text(text)
            print(f"wrote {path}")
    return status


if __name__ == "__main__":
    sys.exit(main())
