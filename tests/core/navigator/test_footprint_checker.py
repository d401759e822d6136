"""FootprintCollisionChecker on a small costmap: free, inflated and lethal cells, off-map poses."""

from __future__ import annotations

import pytest

pytest.importorskip("nav2_msgs.msg", reason="interface packages not built")

from geometry_msgs.msg import Point32, Polygon  # noqa: E402
from nav2_msgs.msg import Costmap  # noqa: E402

from tb4.navigator import FootprintCollisionChecker, PyCostmap2D  # noqa: E402
from tb4.navigator.footprint_collision_checker import LETHAL_OBSTACLE, circle_footprint  # noqa: E402


def grid(size: int = 40, resolution: float = 0.1) -> PyCostmap2D:
    msg = Costmap()
    msg.metadata.size_x = msg.metadata.size_y = size
    msg.metadata.resolution = resolution
    msg.data = [0] * (size * size)
    return PyCostmap2D(msg)


def square(half: float) -> Polygon:
    return Polygon(points=[Point32(x=sx * half, y=sy * half) for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))])


def test_constants_and_requires_costmap() -> None:
    checker = FootprintCollisionChecker()
    assert (checker.LETHAL, checker.INSCRIBED, checker.NO_INFO) == (254, 253, 255)
    with pytest.raises(ValueError, match="setCostmap"):
        checker.pointCost(0, 0)


def test_free_inflated_and_lethal() -> None:
    costmap = grid()
    checker = FootprintCollisionChecker()
    checker.setCostmap(costmap)
    footprint = square(0.3)
    assert checker.footprintCostAtPose(2.0, 2.0, 0.0, footprint) == 0.0
    mx, my = costmap.worldToMapValidated(2.3, 2.0)
    costmap.setCost(mx, my, 100)
    assert checker.footprintCostAtPose(2.0, 2.0, 0.0, footprint) == 100.0
    costmap.setCost(mx, my, LETHAL_OBSTACLE)
    assert checker.footprintCostAtPose(2.0, 2.0, 0.0, footprint) == LETHAL_OBSTACLE
    # Moved away, the same footprint is free again; rotated by 45 degrees its corners miss the cell too.
    assert checker.footprintCostAtPose(1.0, 1.0, 0.785, footprint) == 0.0


def test_steep_edges_miss_no_cell_and_off_map_is_lethal() -> None:
    costmap = grid()
    checker = FootprintCollisionChecker()
    checker.setCostmap(costmap)
    costmap.setCost(20, 25, 200)  # on the steep line from (20, 20) to (21, 30)
    assert checker.lineCost(20, 21, 20, 30) == 200.0
    assert checker.footprintCostAtPose(0.05, 0.05, 0.0, circle_footprint(0.2)) == LETHAL_OBSTACLE
