"""PyCostmap2D over a hand-made nav2_msgs/Costmap: sizes, indexing, conversions, bounds."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("nav2_msgs.msg", reason="interface packages not built")

from nav2_msgs.msg import Costmap  # noqa: E402

from nav2_simple_commander.costmap_2d import PyCostmap2D as UpstreamPath  # noqa: E402
from tb4.navigator import PyCostmap2D  # noqa: E402


def make_costmap(size_x: int = 5, size_y: int = 3, resolution: float = 0.5, origin=(-1.0, 2.0)) -> Costmap:
    msg = Costmap()
    msg.header.frame_id = "map"
    msg.metadata.size_x = size_x
    msg.metadata.size_y = size_y
    msg.metadata.resolution = resolution
    msg.metadata.origin.position.x, msg.metadata.origin.position.y = origin
    msg.data = [(i * 7) % 256 for i in range(size_x * size_y)]
    return msg


def test_sizes_and_metadata() -> None:
    cm = PyCostmap2D(make_costmap())
    assert (cm.getSizeInCellsX(), cm.getSizeInCellsY()) == (5, 3)
    assert cm.getSizeInMetersX() == pytest.approx(2.5) and cm.getSizeInMetersY() == pytest.approx(1.5)
    assert (cm.getOriginX(), cm.getOriginY(), cm.getResolution()) == (-1.0, 2.0, 0.5)
    assert cm.getGlobalFrameID() == "map"
    assert UpstreamPath is PyCostmap2D


def test_row_major_index_and_costs() -> None:
    cm = PyCostmap2D(make_costmap())
    assert cm.getIndex(2, 1) == 7
    assert cm.getCostXY(2, 1) == (7 * 7) % 256 == cm.getCostIdx(7)
    cm.setCost(4, 2, 254)
    assert cm.getCostXY(4, 2) == 254 and cm.costmap.dtype == np.uint8
    with pytest.raises(IndexError):
        cm.getCostXY(5, 0)
    with pytest.raises(ValueError):
        cm.setCost(0, 0, 300)


def test_world_map_round_trip_and_bounds() -> None:
    cm = PyCostmap2D(make_costmap())
    assert cm.mapToWorld(0, 0) == pytest.approx((-0.75, 2.25))
    assert cm.worldToMapValidated(*cm.mapToWorld(3, 2)) == (3, 2)
    assert cm.worldToMapValidated(-1.01, 2.1) == (None, None)
    assert cm.worldToMapValidated(1.6, 2.1) == (None, None)  # x beyond 5 cells
    assert cm.worldToMapValidated(float("nan"), 2.1) == (None, None)


def test_bytes_data_and_size_mismatch() -> None:
    msg = make_costmap(2, 2)
    cm = PyCostmap2D(msg)
    assert list(cm.costmap) == [0, 7, 14, 21]
    bad = make_costmap(2, 2)
    bad.metadata.size_x = 3
    with pytest.raises(ValueError, match="cells"):
        PyCostmap2D(bad)
    with pytest.raises(TypeError):
        PyCostmap2D("not a costmap")
