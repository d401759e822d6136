"""Costmap, map and lifecycle services through the navigator, each checked by its effect on the simulator."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from lifecycle_msgs.srv import GetState
from nav_msgs.msg import OccupancyGrid
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

import tb4
from tb4.navigator import PyCostmap2D, TaskResult, TurtleBot4Directions

from .test_navigator_tasks import make_navigator

D = TurtleBot4Directions
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
WORLDS = Path(tb4.__file__).parent / "worlds"
__all__ = ["make_navigator"]


def beyond(costmap: PyCostmap2D, radius: float) -> np.ndarray:
    """Mask (flat, like PyCostmap2D.costmap) of the cells whose centre is farther than `radius` from the map origin."""
    res = costmap.getResolution()
    xs = costmap.getOriginX() + (np.arange(costmap.getSizeInCellsX()) + 0.5) * res
    ys = costmap.getOriginY() + (np.arange(costmap.getSizeInCellsY()) + 0.5) * res
    return (np.hypot(xs[None, :], ys[:, None]) > radius).ravel()


def lethal_cells(costmap) -> int:
    return int(np.count_nonzero(PyCostmap2D(costmap).costmap >= 253))


def test_costmaps_map_and_lifecycle(start_simulator, ros, make_navigator) -> None:
    # Real time: the lidar re-marks the local costmap at 10 Hz, slow enough to see a clear take effect.
    start_simulator("--rate", "1", "--world", "warehouse")
    nav = make_navigator()
    nav.setInitialPose(nav.getPoseStamped([0.0, 0.0], D.NORTH))
    nav.waitUntilNav2Active()

    # Local costmap: the lidar's marks are gone right after a clear (and come back with the next scans).
    cleared = False
    for _ in range(10):
        before = lethal_cells(nav.getLocalCostmap())
        nav.clearLocalCostmap()
        if lethal_cells(nav.getLocalCostmap()) < before:
            cleared = True
            break
    assert cleared, "clearing the local costmap never removed an obstacle mark"
    nav.clearCostmapAroundRobot(1.0)
    nav.clearCostmapExceptRegion(2.0)

    # Global costmap: static + lidar obstacle layer + inflation, as the TurtleBot 4 runs it. The robot has only been
    # on the dock, so lidar marks (and a clear's effect) can only lie within the layer's reach of it: beyond that the
    # costmap is static + inflation before and after a clear, which never drops the static layer.
    global_before = PyCostmap2D(nav.getGlobalCostmap())
    nav.clearGlobalCostmap()
    nav.clearAllCostmaps()
    global_after = PyCostmap2D(nav.getGlobalCostmap())
    far = beyond(global_after, 2.5 + 0.45 + 0.5)  # obstacle_max_range + inflation_radius + AMCL's slack, from (0, 0)
    assert far.sum() > 0.9 * far.size
    assert np.array_equal(global_before.costmap[far], global_after.costmap[far])
    assert lethal_cells(nav.getGlobalCostmap()) > 0
    assert global_after.getResolution() == pytest.approx(0.06) and global_after.getGlobalFrameID() == "map"

    # changeMap: the map topic and the global costmap switch to the depot.
    map_msg = ros.latest(OccupancyGrid, "map", LATCHED)
    assert ros.wait_for(map_msg, what="map").info.width == 1006
    assert nav.changeMap(str(WORLDS / "depot_map.yaml")) is True
    depot = ros.wait_for(map_msg, lambda m: m.info.width != 1006, what="the new map")
    assert (depot.info.width, depot.info.height) == (755, 380)
    assert PyCostmap2D(nav.getGlobalCostmap()).getSizeInCellsY() < global_after.getSizeInCellsY()
    assert nav.changeMap("/nonexistent/map.yaml") is False
    assert nav.getTaskError()[0] == 1  # RESULT_MAP_DOES_NOT_EXIST
    assert nav.changeMap(WORLDS / "warehouse_map.yaml") is True
    assert ros.wait_for(map_msg, lambda m: m.info.width == 1006, what="the warehouse map again").info.height == 1674

    # Lifecycle: shutdown finalizes the Nav2 nodes (goals are rejected), startup brings them back.
    assert nav.lifecycleShutdown() is True
    state = ros.service(GetState, "bt_navigator/get_state", GetState.Request()).current_state.label
    assert state == "finalized"
    assert nav.spin(0.2) is None and nav.getResult() is TaskResult.UNKNOWN
    assert nav.lifecycleStartup() is True
    assert ros.service(GetState, "bt_navigator/get_state", GetState.Request()).current_state.label == "active"
    nav.waitUntilNav2Active()
    assert nav.getDockedStatus() is True  # still on the dock: nothing moved
    assert nav.getPath(None, nav.getPoseStamped([-3.0, 0.0], D.EAST)) is not None  # the planner serves again


def test_a_namespaced_robot(start_simulator, make_navigator) -> None:
    start_simulator("--rate", "max", "--hold", "--world", "warehouse", "--namespace", "robot1")
    nav = make_navigator(namespace="robot1")
    assert nav.getDockedStatus() is True
    nav.setInitialPose(nav.getPoseStamped([0.0, 0.0], D.NORTH))
    nav.waitUntilNav2Active()
    assert nav.undock()
    assert nav.startToPose(nav.getPoseStamped([-2.0, 0.0], D.EAST)) is TaskResult.SUCCEEDED
    assert nav.lifecycleShutdown() and nav.lifecycleStartup()  # only robot1's managers
    assert nav.getPath(None, nav.getPoseStamped([-3.0, 0.0], D.EAST)) is not None
