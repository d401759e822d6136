"""map_server: the latched `map` topic and `map_server/load_map`, which switches the simulator and the core to
another map file (and tells the simulator, whose world no longer matches)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from nav2_msgs.srv import LoadMap
from nav_msgs.msg import OccupancyGrid

from tb4.config import ConfigError
from tb4.core.maps import OccupancyMap, load_map
from tb4.ros.convert import occupancy_grid_msg
from tb4.ros.qos import LATCHED
from tb4.ros.replies import create_service

if TYPE_CHECKING:
    from tb4.ros.nav2.interfaces import Nav2Interfaces

__all__ = ["MapServer", "MapChangeHandler"]

#: Called after load_map switched maps, with the new grid and its file.
MapChangeHandler = Callable[[OccupancyMap, Path], None]


class MapServer:
    """The map_server node: publishes the core's map, loads another on request."""

    def __init__(self, nav2: Nav2Interfaces, on_map_change: MapChangeHandler | None = None) -> None:
        self.loop = nav2.loop
        self.nav = nav2.nav
        self.on_map_change = on_map_change
        self.node = nav2.nodes["map_server"]
        self.map_pub = self.node.create_publisher(OccupancyGrid, "map", LATCHED)
        self.publish_map(self.nav.grid, 0.0)
        create_service(self.node, LoadMap, "~/load_map", self._load, callback_group=nav2.callback_group)

    def publish_map(self, grid: OccupancyMap, now: float) -> OccupancyGrid:
        msg = occupancy_grid_msg(grid, now)
        self.map_pub.publish(msg)
        return msg

    def _load(self, request: Any, response: Any) -> Any:
        logger = self.node.get_logger()
        url = request.map_url
        path = Path(url[len("file://") :] if url.startswith("file://") else url)
        if not path.is_file():
            response.result = LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST
            logger.error(f"load_map: no such map file: {path}")
            return response
        try:
            grid = load_map(path)
        except ConfigError as exc:
            bad_image = exc.key == "image"
            response.result = (
                LoadMap.Response.RESULT_INVALID_MAP_DATA if bad_image else LoadMap.Response.RESULT_INVALID_MAP_METADATA
            )
            logger.error(f"load_map: {exc}")
            return response

        def switch() -> float:
            self.loop.sim.set_grid(grid)
            self.nav.set_map(grid)
            return self.loop.sim.time

        try:
            now = self.loop.call_outside_replay(switch, "map_server/load_map switched the map")
        except ValueError as exc:  # a fleet's shared world
            response.result = LoadMap.Response.RESULT_UNDEFINED_FAILURE
            logger.error(f"load_map: {exc}")
            return response
        response.map = self.publish_map(grid, now)
        if self.on_map_change is not None:
            self.on_map_change(grid, path)
        response.result = LoadMap.Response.RESULT_SUCCESS
        logger.info(f"switched to map {path}")
        return response
