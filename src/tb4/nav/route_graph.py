"""Route graphs in Nav2 route server's GeoJSON format: loading with validation, and lookups.

The file is a GeoJSON FeatureCollection. A `Point` feature is a node (`properties.id`, optional `frame`,
`metadata`, `operations`); a `LineString` / `MultiLineString` feature is a *directed* edge from
`properties.startid` to `properties.endid` (optional `cost`, `overridable`, `metadata`, `operations`); a
two-way aisle is two edges. As in nav2_route, an edge's own geometry is not used: it runs straight between
its nodes. Every mistake is reported as a tb4.config.ConfigError naming the file and the feature, with a
"did you mean" for a misspelt property.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tb4.config import ConfigError, check_keys

__all__ = ["RouteNode", "RouteEdge", "RouteGraph", "load_route_graph", "parse_route_graph"]

_NODE_KEYS = ("id", "frame", "metadata", "operations")
_EDGE_KEYS = ("id", "startid", "endid", "cost", "overridable", "metadata", "operations")
_TOP_KEYS = ("type", "name", "crs", "date_generated", "features")
_TRIGGERS = ("NODE", "ON_ENTER", "ON_EXIT")
MAX_ID = 65535  # ids travel in uint16 fields (RouteNode.nodeid, RouteEdge.edgeid, the action goals)


@dataclass(frozen=True)
class RouteNode:
    id: int
    x: float
    y: float
    metadata: dict[str, Any] = field(default_factory=dict)
    operations: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RouteEdge:
    """A directed edge. `cost` > 0 with `overridable` false is used as is; otherwise the edge scorers decide."""

    id: int
    start: int
    end: int
    cost: float = 0.0
    overridable: bool = True
    metadata: dict[str, Any] = field(default_factory=dict)
    operations: dict[str, Any] = field(default_factory=dict)


@dataclass
class RouteGraph:
    """Nodes and directed edges by id, plus each node's outgoing edges."""

    nodes: dict[int, RouteNode]
    edges: dict[int, RouteEdge]
    source: str = "<graph>"
    name: str = ""
    outgoing: dict[int, list[RouteEdge]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.outgoing = {nid: [] for nid in self.nodes}
        for edge in self.edges.values():
            self.outgoing[edge.start].append(edge)
        self._ids = np.array(list(self.nodes), dtype=np.int64)
        self._xy = np.array([(n.x, n.y) for n in self.nodes.values()], dtype=np.float64).reshape(-1, 2)

    def length(self, edge: RouteEdge) -> float:
        a, b = self.nodes[edge.start], self.nodes[edge.end]
        return math.hypot(b.x - a.x, b.y - a.y)

    def nearest_nodes(self, x: float, y: float, count: int = 1) -> list[int]:
        """Ids of the `count` nodes closest to (x, y), closest first (Nav2's node spatial tree query)."""
        d2 = (self._xy[:, 0] - x) ** 2 + (self._xy[:, 1] - y) ** 2
        order = np.argsort(d2, kind="stable")[: max(1, count)]
        return [int(self._ids[i]) for i in order]

    def segments(self) -> list[tuple[float, float, float, float]]:
        """(x0, y0, x1, y1) per edge, each undirected pair once (for drawing)."""
        seen: set[tuple[int, int]] = set()
        out = []
        for e in self.edges.values():
            key = (min(e.start, e.end), max(e.start, e.end))
            if key in seen:
                continue
            seen.add(key)
            a, b = self.nodes[e.start], self.nodes[e.end]
            out.append((a.x, a.y, b.x, b.y))
        return out


def load_route_graph(path: str | Path) -> RouteGraph:
    """Read and validate a GeoJSON route graph file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(path, None, "route graph file not found") from None
    except (OSError, UnicodeDecodeError, ValueError) as exc:  # ValueError: e.g. a NUL byte in the path
        raise ConfigError(path, None, f"cannot read route graph ({exc})") from None
    try:
        raw = json.loads(text, parse_constant=_reject_constant)
    except (json.JSONDecodeError, ValueError) as exc:
        raise ConfigError(path, None, f"not valid JSON ({exc})") from None
    return parse_route_graph(raw, path)


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON allows")


def parse_route_graph(raw: Any, source: str | Path = "<graph>") -> RouteGraph:
    """Validate an already-decoded GeoJSON object and build the graph."""
    if not isinstance(raw, Mapping):
        raise ConfigError(source, None, f"expected a GeoJSON FeatureCollection object, got {type(raw).__name__}")
    check_keys(raw, _TOP_KEYS, source, required=("features",))
    if raw.get("type", "FeatureCollection") != "FeatureCollection":
        raise ConfigError(source, "type", f"expected 'FeatureCollection', got {raw.get('type')!r}")
    features = raw["features"]
    if not isinstance(features, list):
        raise ConfigError(source, "features", f"expected a list of features, got {type(features).__name__}")
    nodes: dict[int, RouteNode] = {}
    edge_specs: list[tuple[str, Mapping[str, Any]]] = []
    for i, feature in enumerate(features):
        key = f"features[{i}]"
        if not isinstance(feature, Mapping):
            raise ConfigError(source, key, f"expected a GeoJSON Feature object, got {feature!r:.80}")
        geometry = feature.get("geometry")
        props = feature.get("properties")
        if not isinstance(geometry, Mapping) or not isinstance(props, Mapping):
            raise ConfigError(source, key, "a feature needs a 'geometry' object and a 'properties' object")
        kind = geometry.get("type")
        if kind == "Point":
            node = _node(props, geometry, source, key)
            if node.id in nodes:
                raise ConfigError(source, f"{key}.properties.id", f"node id {node.id} is used twice")
            nodes[node.id] = node
        elif kind in ("LineString", "MultiLineString"):
            edge_specs.append((key, props))
        else:
            raise ConfigError(
                source, f"{key}.geometry.type", f"expected Point (a node) or LineString (an edge), got {kind!r}"
            )
    edges: dict[int, RouteEdge] = {}
    for key, props in edge_specs:
        edge = _edge(props, nodes, source, key)
        if edge.id in edges:
            raise ConfigError(source, f"{key}.properties.id", f"edge id {edge.id} is used twice")
        edges[edge.id] = edge
    if not nodes or not edges:
        raise ConfigError(source, "features", "the graph is malformed: it needs at least one node and one edge")
    name = raw.get("name", "")
    return RouteGraph(nodes=nodes, edges=edges, source=str(source), name=name if isinstance(name, str) else "")


def _id(value: Any, source: str | Path, key: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_ID:
        raise ConfigError(source, key, f"expected an integer id in 0..{MAX_ID}, got {value!r}")
    return int(value)


def _finite(value: Any, source: str | Path, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise ConfigError(source, key, f"expected a finite number, got {value!r}")
    return float(value)


def _mapping(value: Any, source: str | Path, key: str) -> dict[str, Any]:
    if not isinstance(value, Mapping):
        raise ConfigError(source, key, f"expected an object, got {value!r:.80}")
    return dict(value)


def _operations(props: Mapping[str, Any], source: str | Path, key: str) -> dict[str, Any]:
    ops = _mapping(props.get("operations", {}), source, f"{key}.operations")
    for name, op in ops.items():
        op_key = f"{key}.operations.{name}"
        op = _mapping(op, source, op_key)
        check_keys(op, ("type", "trigger", "metadata"), source, prefix=f"{op_key}.", required=("type", "trigger"))
        if op["trigger"] not in _TRIGGERS:
            raise ConfigError(
                source, f"{op_key}.trigger", f"expected one of {', '.join(_TRIGGERS)}, got {op['trigger']!r}"
            )
    return ops


def _node(props: Mapping[str, Any], geometry: Mapping[str, Any], source: str | Path, key: str) -> RouteNode:
    check_keys(props, _NODE_KEYS, source, prefix=f"{key}.properties.", required=("id",))
    node_id = _id(props["id"], source, f"{key}.properties.id")
    frame = props.get("frame", "map")
    if frame != "map":
        raise ConfigError(source, f"{key}.properties.frame", f"only the 'map' frame is supported, got {frame!r}")
    coords = geometry.get("coordinates")
    if not isinstance(coords, (list, tuple)) or len(coords) < 2:
        raise ConfigError(source, f"{key}.geometry.coordinates", f"expected [x, y], got {coords!r:.80}")
    x = _finite(coords[0], source, f"{key}.geometry.coordinates[0]")
    y = _finite(coords[1], source, f"{key}.geometry.coordinates[1]")
    metadata = _mapping(props.get("metadata", {}), source, f"{key}.properties.metadata")
    return RouteNode(node_id, x, y, metadata, _operations(props, source, f"{key}.properties"))


def _edge(props: Mapping[str, Any], nodes: Mapping[int, RouteNode], source: str | Path, key: str) -> RouteEdge:
    prefix = f"{key}.properties."
    check_keys(props, _EDGE_KEYS, source, prefix=prefix, required=("id", "startid", "endid"))
    edge_id = _id(props["id"], source, f"{prefix}id")
    ends = []
    for end_key in ("startid", "endid"):
        node_id = _id(props[end_key], source, f"{prefix}{end_key}")
        if node_id not in nodes:
            raise ConfigError(
                source, f"{prefix}{end_key}", f"edge {edge_id} refers to node {node_id}, which is not in the graph"
            )
        ends.append(node_id)
    if ends[0] == ends[1]:
        raise ConfigError(source, key, f"edge {edge_id} starts and ends at node {ends[0]}")
    cost = _finite(props.get("cost", 0.0), source, f"{prefix}cost")
    if cost < 0.0:
        raise ConfigError(source, f"{prefix}cost", f"must be >= 0, got {cost}")
    overridable = props.get("overridable", True)
    if not isinstance(overridable, bool):
        raise ConfigError(source, f"{prefix}overridable", f"expected true or false, got {overridable!r}")
    if not overridable and cost <= 0.0:
        raise ConfigError(source, f"{prefix}cost", f"edge {edge_id} is not overridable, so it needs a cost > 0")
    metadata = _mapping(props.get("metadata", {}), source, f"{prefix}metadata")
    for meta_key in ("speed_limit", "penalty"):
        if meta_key in metadata:
            value = _finite(metadata[meta_key], source, f"{prefix}metadata.{meta_key}")
            if meta_key == "speed_limit" and value <= 0.0:
                raise ConfigError(source, f"{prefix}metadata.speed_limit", f"must be > 0, got {value}")
    return RouteEdge(edge_id, ends[0], ends[1], cost, overridable, metadata, _operations(props, source, key))
