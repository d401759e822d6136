"""The global costmap's obstacle layer: Nav2's marking and clearing semantics on the whole map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.nav.costmap import LETHAL, CostmapParams, GlobalCostmap

pytestmark = pytest.mark.core


def grid() -> OccupancyMap:
    data = np.zeros((200, 200), dtype=np.int8)  # 10 x 10 m at 0.05
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    return OccupancyMap(data, 0.05)


def params(**kw: float) -> CostmapParams:
    base = {"obstacle_layer": True, "obstacle_max_range": 2.5, "raytrace_max_range": 3.0}
    return CostmapParams(**{**base, **kw})  # type: ignore[arg-type]


def test_marks_only_within_obstacle_max_range_and_persist_outside_the_sensor_view() -> None:
    g = GlobalCostmap(grid(), params())
    g.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0], [4.9, 5.0 + 0.0]]), np.zeros((0, 2)))
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL
    assert g.costmap.cost_at(4.9, 5.0) < LETHAL  # 2.9 m away: beyond obstacle_max_range, not marked
    # the robot drives off: marks far from the sensor stay (no decay), as in Nav2
    g.update_obstacles(8.0, 8.0, np.zeros((0, 2)), np.array([[8.0, 9.0]]))
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL


def test_a_beam_through_a_mark_clears_it_but_not_a_static_wall() -> None:
    g = GlobalCostmap(grid(), params())
    g.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0]]), np.zeros((0, 2)))
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL
    # the obstacle left: a beam now reaches the east wall through its cell
    g.update_obstacles(2.0, 5.0, np.array([[9.92, 5.0]]), np.zeros((0, 2)))
    assert g.costmap.cost_at(4.0, 5.0) < LETHAL
    assert g.costmap.cost_at(9.95, 5.0) == LETHAL  # static wall kept
    # an empty beam clears up to raytrace_max_range only
    g.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0], [2.0, 7.0]]), np.zeros((0, 2)))
    g.update_obstacles(0.5, 5.0, np.zeros((0, 2)), np.array([[12.5, 5.0]]))
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL  # 3.5 m from the sensor: beyond raytrace reach


def test_clearing_services_and_bad_input() -> None:
    g = GlobalCostmap(grid(), params())
    g.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0], [2.0, 7.0], [np.nan, 1.0], [np.inf, 2.0]]), np.zeros((0, 2)))
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL and g.costmap.cost_at(2.0, 7.0) == LETHAL
    g.clear_around(4.0, 5.0, 1.0)
    assert g.costmap.cost_at(4.0, 5.0) < LETHAL and g.costmap.cost_at(2.0, 7.0) == LETHAL
    g.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0]]), np.zeros((0, 2)))
    g.clear_except_region(4.0, 5.0, 1.0)
    assert g.costmap.cost_at(4.0, 5.0) == LETHAL and g.costmap.cost_at(2.0, 7.0) < LETHAL
    g.clear()
    assert not g.obstacles.marks.any() and g.costmap.cost_at(4.0, 5.0) == 0
    with pytest.raises(ValueError, match="finite"):
        g.update_obstacles(math.nan, 5.0, np.zeros((0, 2)), np.zeros((0, 2)))
    off = GlobalCostmap(grid(), CostmapParams())  # layer disabled: scans change nothing
    before = off.costmap.data.copy()
    off.update_obstacles(2.0, 5.0, np.array([[4.0, 5.0]]), np.zeros((0, 2)))
    assert np.array_equal(off.costmap.data, before)


def test_enabled_in_nav2_yaml_planning_remembers_beyond_the_local_window(kit, open_map) -> None:
    from tb4.nav.params import load_nav2_params
    from tb4.sim.obstacles import Obstacle

    layer = {"obstacle_layer": {"enabled": True}}
    params = load_nav2_params(overrides={"global_costmap": {"global_costmap": {"ros__parameters": layer}}})
    box = Obstacle(shape="circle", radius=0.4, path=((2.5, 1.0),))
    h = kit.Harness(open_map, (1.0, 1.0, 0.0), obstacles=[box], params=params)
    h.settle(0.2)
    assert h.core.current_local_costmap().cost_at(2.1, 1.0) >= 253  # idle: a reader's fresh view sees it
    assert h.core.global_costmap.costmap.cost_at(2.1, 1.0) != LETHAL  # ... and reading changed nothing
    h.run(h.core.start_wait(0.3), max_time=1.0)  # a task: the costmaps take the scan at their own pace
    assert h.core.global_costmap.costmap.cost_at(2.1, 1.0) == LETHAL
    h.core.clear_local()  # the local window forgets; the global obstacle layer does not
    assert h.core.global_costmap.costmap.cost_at(2.1, 1.0) == LETHAL
    path = h.core.compute_path(None, (4.0, 1.0, 0.0)).path
    assert np.min(np.hypot(path[:, 0] - 2.5, path[:, 1] - 1.0)) > 0.4
    h.core.clear_global()
    straight = h.core.compute_path(None, (4.0, 1.0, 0.0)).path
    assert np.max(np.abs(straight[:, 1] - 1.0)) < 0.1
