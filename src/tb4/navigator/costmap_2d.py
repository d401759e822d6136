"""PyCostmap2D: cell access to a nav2_msgs/Costmap (as returned by getGlobalCostmap), Nav2's Python API."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["PyCostmap2D"]


class PyCostmap2D:
    """Row-major costs (index = my * size_x + mx) with map<->world conversions; cell (0, 0) at the origin."""

    def __init__(self, occupancy_map: Any) -> None:
        meta = getattr(occupancy_map, "metadata", None)
        if meta is None or not hasattr(occupancy_map, "data"):
            raise TypeError(f"PyCostmap2D needs a nav2_msgs/Costmap, got {type(occupancy_map).__name__}")
        self.size_x: int = int(meta.size_x)
        self.size_y: int = int(meta.size_y)
        self.resolution: float = float(meta.resolution)
        self.origin_x: float = float(meta.origin.position.x)
        self.origin_y: float = float(meta.origin.position.y)
        self.global_frame_id: str = occupancy_map.header.frame_id
        self.costmap_timestamp: Any = occupancy_map.header.stamp
        data = occupancy_map.data
        if isinstance(data, (bytes, bytearray, memoryview)):
            costs = np.frombuffer(bytes(data), dtype=np.uint8).copy()
        else:
            costs = np.asarray(data, dtype=np.uint8).copy()
        if costs.size != self.size_x * self.size_y:
            raise ValueError(f"costmap has {costs.size} cells, metadata says {self.size_x} x {self.size_y}")
        if self.resolution <= 0 or not math.isfinite(self.resolution):
            raise ValueError(f"costmap resolution must be positive, got {self.resolution}")
        self.costmap: NDArray[np.uint8] = costs

    def getSizeInCellsX(self) -> int:
        return self.size_x

    def getSizeInCellsY(self) -> int:
        return self.size_y

    def getSizeInMetersX(self) -> float:
        return self.size_x * self.resolution

    def getSizeInMetersY(self) -> float:
        return self.size_y * self.resolution

    def getOriginX(self) -> float:
        return self.origin_x

    def getOriginY(self) -> float:
        return self.origin_y

    def getResolution(self) -> float:
        return self.resolution

    def getGlobalFrameID(self) -> str:
        return self.global_frame_id

    def getCostmapTimestamp(self) -> Any:
        return self.costmap_timestamp

    def getIndex(self, mx: int, my: int) -> int:
        return int(my) * self.size_x + int(mx)

    def _check_cell(self, mx: int, my: int) -> None:
        if not (0 <= mx < self.size_x and 0 <= my < self.size_y):
            raise IndexError(f"cell ({mx}, {my}) is outside the {self.size_x} x {self.size_y} costmap")

    def getCostXY(self, mx: int, my: int) -> np.uint8:
        self._check_cell(mx, my)
        return np.uint8(self.costmap[self.getIndex(mx, my)])

    def getCostIdx(self, index: int) -> np.uint8:
        return np.uint8(self.costmap[index])

    def setCost(self, mx: int, my: int, cost: int) -> None:
        self._check_cell(mx, my)
        if not 0 <= int(cost) <= 255:
            raise ValueError(f"cost must be 0..255, got {cost}")
        self.costmap[self.getIndex(mx, my)] = cost

    def mapToWorld(self, mx: int, my: int) -> tuple[float, float]:
        """World coordinates of the cell's centre."""
        return (self.origin_x + (mx + 0.5) * self.resolution, self.origin_y + (my + 0.5) * self.resolution)

    def worldToMapValidated(self, wx: float, wy: float) -> tuple[int | None, int | None]:
        """The cell holding (wx, wy), or (None, None) outside the costmap (or for NaN)."""
        if not (math.isfinite(wx) and math.isfinite(wy)) or wx < self.origin_x or wy < self.origin_y:
            return (None, None)
        mx = int((wx - self.origin_x) // self.resolution)
        my = int((wy - self.origin_y) // self.resolution)
        if mx < self.size_x and my < self.size_y:
            return (mx, my)
        return (None, None)
