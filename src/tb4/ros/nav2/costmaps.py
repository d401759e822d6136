"""The global_costmap and local_costmap nodes: their clear services, get_costmap, and the `costmap` topics
(the global one latched and sent when it changes, the local one twice a second while someone listens)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from nav2_msgs.msg import Costmap, CostmapMetaData
from nav2_msgs.srv import ClearCostmapAroundRobot, ClearCostmapExceptRegion, ClearEntireCostmap, GetCostmap
from nav_msgs.msg import OccupancyGrid

from tb4.core.maps import OccupancyMap
from tb4.ros.convert import costmap_to_occupancy_values, occupancy_grid_msg, pose_msg, time_msg
from tb4.ros.qos import LATCHED
from tb4.ros.replies import create_service

if TYPE_CHECKING:
    from tb4.ros.nav2.interfaces import Nav2Interfaces

__all__ = ["CostmapServers", "GLOBAL_PERIOD", "LOCAL_PERIOD"]

GLOBAL_PERIOD = 1.0  # s of sim time between two checks for a new global costmap
LOCAL_PERIOD = 0.5  # s of sim time between two local costmaps


class CostmapServers:
    """Both costmap nodes' services and topics, reading the core's costmaps in the loop."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        self.loop = nav2.loop
        self.nav = nav2.nav
        nav = nav2.loop.inputs.nav  # clearing changes what the robot does next: journaled inputs
        glob, local = nav2.nodes["global_costmap/global_costmap"], nav2.nodes["local_costmap/local_costmap"]
        group = nav2.callback_group
        create_service(
            glob,
            ClearEntireCostmap,
            "clear_entirely_global_costmap",
            self._clear(nav.clear_global),
            callback_group=group,
        )
        create_service(
            local,
            ClearEntireCostmap,
            "clear_entirely_local_costmap",
            self._clear(nav.clear_local),
            callback_group=group,
        )
        for node, except_region, around in (
            (glob, nav.clear_global_except, nav.clear_global_around),
            (local, nav.clear_local_except, nav.clear_local_around),
        ):
            create_service(
                node,
                ClearCostmapExceptRegion,
                "clear_costmap_except_region",
                self._clear_by_distance(except_region),
                callback_group=group,
            )
            create_service(
                node,
                ClearCostmapAroundRobot,
                "clear_costmap_around_robot",
                self._clear_by_distance(around),
                callback_group=group,
            )
        create_service(glob, GetCostmap, "get_costmap", self._get_costmap("global"), callback_group=group)
        create_service(local, GetCostmap, "get_costmap", self._get_costmap("local"), callback_group=group)
        self.global_pub = glob.create_publisher(OccupancyGrid, "costmap", LATCHED)
        self.local_pub = local.create_publisher(OccupancyGrid, "costmap", 1)
        self._published_global: Any = None
        self.loop.every(GLOBAL_PERIOD, self._publish_global)
        self.loop.every(LOCAL_PERIOD, self._publish_local)

    def _clear(self, fn: Callable[[], None]) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            fn()
            return response

        return handler

    def _clear_by_distance(self, fn: Callable[[float], None]) -> Callable:
        def handler(request: Any, response: Any) -> Any:
            distance = float(request.reset_distance)
            if math.isfinite(distance) and distance >= 0:
                fn(distance)
            return response

        return handler

    def _costmap(self, which: str) -> Any:
        return self.nav.global_costmap.costmap if which == "global" else self.nav.current_local_costmap()

    def _frame(self, which: str) -> str:
        """The local costmap is in `odom` until the robot is localized (there is no map pose yet)."""
        return "map" if (which == "global" or self.nav.localizer.is_localized) else "odom"

    def _get_costmap(self, which: str) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            costmap, now, frame = self.loop.call(
                lambda: (self._costmap(which).copy(), self.loop.sim.time, self._frame(which))
            )
            msg = Costmap()
            msg.header.frame_id = frame
            msg.header.stamp = time_msg(now)
            meta = CostmapMetaData()
            meta.map_load_time = time_msg(0.0)
            meta.update_time = time_msg(now)
            meta.layer = "master"
            meta.resolution = float(costmap.resolution)
            meta.size_y, meta.size_x = (int(n) for n in costmap.data.shape)
            meta.origin = pose_msg(costmap.origin_x, costmap.origin_y, 0.0)
            msg.metadata = meta
            msg.data = costmap.data.ravel().tobytes()
            response.map = msg
            return response

        return handler

    def _publish_global(self, now: float) -> None:
        costmap = self.nav.global_costmap.costmap
        if costmap is self._published_global:
            return
        self._published_global = costmap
        self.global_pub.publish(_occupancy_grid(costmap, now, "map"))

    def _publish_local(self, now: float) -> None:
        if self.local_pub.get_subscription_count() == 0:
            return
        self.local_pub.publish(_occupancy_grid(self._costmap("local"), now, self._frame("local")))


def _occupancy_grid(costmap: Any, now: float, frame: str) -> OccupancyGrid:
    """A costmap as an OccupancyGrid (Nav2's costmap topic: 0..100 scaled from 0..254, -1 unknown)."""
    grid = OccupancyMap(
        data=costmap_to_occupancy_values(costmap),
        resolution=costmap.resolution,
        origin_x=costmap.origin_x,
        origin_y=costmap.origin_y,
    )
    return occupancy_grid_msg(grid, now, frame)
