"""Map and costmap services. Upstream methods here: changeMap, clearAllCostmaps, clearLocalCostmap,
clearGlobalCostmap, clearCostmapExceptRegion, clearCostmapAroundRobot, getGlobalCostmap, getLocalCostmap."""

from __future__ import annotations

import os
from typing import Any

from nav2_msgs.msg import Costmap
from nav2_msgs.srv import ClearCostmapAroundRobot, ClearCostmapExceptRegion, ClearEntireCostmap, GetCostmap, LoadMap

from tb4.navigator._base import NavigatorBase
from tb4.navigator._validate import check_number

__all__ = ["CostmapMixin", "COSTMAP_SERVICES"]

COSTMAP_SERVICES: dict[str, Any] = {
    "map_server/load_map": LoadMap,
    "global_costmap/clear_entirely_global_costmap": ClearEntireCostmap,
    "local_costmap/clear_entirely_local_costmap": ClearEntireCostmap,
    "local_costmap/clear_costmap_except_region": ClearCostmapExceptRegion,
    "local_costmap/clear_costmap_around_robot": ClearCostmapAroundRobot,
    "global_costmap/get_costmap": GetCostmap,
    "local_costmap/get_costmap": GetCostmap,
}
_LOAD_MAP_REASONS = {
    LoadMap.Response.RESULT_MAP_DOES_NOT_EXIST: "Map does not exist",
    LoadMap.Response.RESULT_INVALID_MAP_DATA: "Invalid map data",
    LoadMap.Response.RESULT_INVALID_MAP_METADATA: "Invalid map metadata",
    LoadMap.Response.RESULT_UNDEFINED_FAILURE: "Undefined failure",
}


class CostmapMixin(NavigatorBase):
    def _setup_costmap_clients(self) -> None:
        for name, srv_type in COSTMAP_SERVICES.items():
            self._calls.add(srv_type, name)

    def changeMap(self, map_filepath: str | os.PathLike[str]) -> bool:
        """Ask the map server to load another map (YAML path); True on success."""
        if not isinstance(map_filepath, (str, os.PathLike)):
            raise TypeError(f"map_filepath must be a path string, got {type(map_filepath).__name__}")
        path = os.fspath(map_filepath)
        if not path:
            raise ValueError("map_filepath is empty")
        self.clearLastError()
        request = LoadMap.Request(map_url=path)
        response = self._calls.call(LoadMap, "map_server/load_map", request, response_timeout=self.timeouts.result)
        if response.result != LoadMap.Response.RESULT_SUCCESS:
            reason = _LOAD_MAP_REASONS.get(response.result, "Unknown")
            self.setLastError(int(response.result), f"{reason}: {path}")
            self.error(f"Change map request failed: {reason} ({path})!")
            return False
        self.info("Change map request was successful!")
        return True

    def clearAllCostmaps(self) -> None:
        """Clear the local and the global costmap."""
        self.clearLastError()
        self.clearLocalCostmap()
        self.clearGlobalCostmap()

    def clearLocalCostmap(self) -> None:
        self._calls.call(ClearEntireCostmap, "local_costmap/clear_entirely_local_costmap", ClearEntireCostmap.Request())

    def clearGlobalCostmap(self) -> None:
        self._calls.call(
            ClearEntireCostmap, "global_costmap/clear_entirely_global_costmap", ClearEntireCostmap.Request()
        )

    def clearCostmapExceptRegion(self, reset_distance: float) -> None:
        """Clear the local costmap outside a square of `reset_distance` metres around the robot."""
        d = check_number(reset_distance, "reset_distance", non_negative=True)
        request = ClearCostmapExceptRegion.Request(reset_distance=d)
        self._calls.call(ClearCostmapExceptRegion, "local_costmap/clear_costmap_except_region", request)

    def clearCostmapAroundRobot(self, reset_distance: float) -> None:
        """Clear the local costmap inside a square of `reset_distance` metres around the robot."""
        d = check_number(reset_distance, "reset_distance", non_negative=True)
        request = ClearCostmapAroundRobot.Request(reset_distance=d)
        self._calls.call(ClearCostmapAroundRobot, "local_costmap/clear_costmap_around_robot", request)

    def getGlobalCostmap(self) -> Costmap:
        """The global costmap (nav2_msgs/Costmap); wrap it in PyCostmap2D to query cells."""
        return self._calls.call(GetCostmap, "global_costmap/get_costmap", GetCostmap.Request(), idempotent=True).map

    def getLocalCostmap(self) -> Costmap:
        """The local (rolling) costmap (nav2_msgs/Costmap)."""
        return self._calls.call(GetCostmap, "local_costmap/get_costmap", GetCostmap.Request(), idempotent=True).map
