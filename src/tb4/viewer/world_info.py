"""The page's view of a tb4 world (its name, docks, named destinations and route graph), from the world the
simulator announces on its `world` topic or the one given with `tb4 view --world`. Without either (a real robot)
the page has no world and draws from /map alone. Plain Python: no rclpy."""

from __future__ import annotations

import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tb4.config import ConfigError

__all__ = ["world_info", "WorldInfoCache"]


def world_info(world: Any) -> dict[str, Any]:
    """The page's view of a loaded tb4 world (tb4.sim.world.World).

    `docks` is every dock the world lists, in order (a fleet puts robot K on the K-th), each with the label the
    page draws; `dock` stays the first one for pages and readers that know only the one-dock form.
    """
    docks = _dock_infos(world.all_docks)
    return {
        "name": world.name,
        "dock": {k: docks[0][k] for k in ("x", "y", "yaw")},
        "docks": docks,
        "destinations": [
            {"name": d.name, "x": d.x, "y": d.y, "yaw": d.yaw, "description": d.description}
            for d in world.destinations.values()
        ],
        "route_graph": _route_graph_info(getattr(world, "route_graph", None)),
    }


def _dock_infos(docks: Sequence[tuple[float, float, float]]) -> list[dict[str, Any]]:
    """Each dock pose (x, y, yaw) with its label: "dock" when there is one, else "dock 1".."dock N" (the world
    file gives docks no names; robot K of a fleet starts on dock K)."""
    single = len(docks) == 1
    return [
        {"x": x, "y": y, "yaw": yaw, "label": "dock" if single else f"dock {i + 1}"}
        for i, (x, y, yaw) in enumerate(docks)
    ]


def _route_graph_info(path: Path | None) -> dict[str, Any] | None:
    """Nodes [id, x, y] and undirected edges [x0, y0, x1, y1] of a route graph file (None without one)."""
    if path is None:
        return None
    from tb4.nav.route_graph import load_route_graph

    try:
        graph = load_route_graph(path)
    except ConfigError:  # a broken graph must not break the viewer
        return None
    return {
        "nodes": [[n.id, n.x, n.y] for n in graph.nodes.values()],
        "edges": [list(seg) for seg in graph.segments()],
    }


class WorldInfoCache:
    """world_info by world reference (a shipped world's name or a world file), each world loaded once.

    A reference that does not load (a world file only on the simulator's machine, a broken file) gives None and
    the reason in `errors`: the viewer then works from the map alone rather than failing.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._infos: dict[str, dict[str, Any] | None] = {}
        self.errors: dict[str, str] = {}

    def get(self, reference: str) -> dict[str, Any] | None:
        if not reference:
            return None
        with self._lock:
            if reference in self._infos:
                return self._infos[reference]
        from tb4.sim.world import load_world

        try:
            info: dict[str, Any] | None = world_info(load_world(reference))
        except (ConfigError, OSError, ValueError) as exc:
            info = None
            self.errors[reference] = str(exc)
        with self._lock:
            self._infos[reference] = info
        return info
