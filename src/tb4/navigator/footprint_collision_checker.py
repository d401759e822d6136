"""FootprintCollisionChecker: the worst cost under a robot footprint (polygon) on a PyCostmap2D."""

from __future__ import annotations

import math

from geometry_msgs.msg import Point32, Polygon

from tb4.navigator.costmap_2d import PyCostmap2D

__all__ = [
    "FootprintCollisionChecker",
    "NO_INFORMATION",
    "LETHAL_OBSTACLE",
    "INSCRIBED_INFLATED_OBSTACLE",
    "MAX_NON_OBSTACLE",
    "FREE_SPACE",
    "circle_footprint",
]

NO_INFORMATION = 255
LETHAL_OBSTACLE = 254
INSCRIBED_INFLATED_OBSTACLE = 253
MAX_NON_OBSTACLE = 252
FREE_SPACE = 0


class FootprintCollisionChecker:
    """Costs along the footprint's edges; LETHAL_OBSTACLE as soon as an edge touches one or leaves the map."""

    LETHAL = LETHAL_OBSTACLE
    INSCRIBED = INSCRIBED_INFLATED_OBSTACLE
    NO_INFO = NO_INFORMATION

    def __init__(self) -> None:
        self.costmap_: PyCostmap2D | None = None

    def setCostmap(self, costmap: PyCostmap2D) -> None:
        if not isinstance(costmap, PyCostmap2D):
            raise TypeError(f"setCostmap needs a PyCostmap2D, got {type(costmap).__name__}")
        self.costmap_ = costmap

    def _costmap(self) -> PyCostmap2D:
        if self.costmap_ is None:
            raise ValueError("Costmap not specified, use setCostmap to specify the costmap first")
        return self.costmap_

    def worldToMapValidated(self, wx: float, wy: float) -> tuple[int | None, int | None]:
        return self._costmap().worldToMapValidated(wx, wy)

    def pointCost(self, x: int, y: int) -> int:
        return int(self._costmap().getCostXY(x, y))

    def lineCost(self, x0: int, x1: int, y0: int, y1: int, step_size: float = 0.5) -> float:
        """Max cost of the cells on the segment (map coordinates), sampled along its longer axis."""
        if step_size <= 0:
            raise ValueError("step_size must be a positive number")
        steps = max(1, math.ceil(max(abs(x1 - x0), abs(y1 - y0)) / step_size))
        worst = 0.0
        for i in range(steps + 1):
            t = i / steps
            cost = self.pointCost(int(round(x0 + (x1 - x0) * t)), int(round(y0 + (y1 - y0) * t)))
            if cost == LETHAL_OBSTACLE:
                return float(cost)
            worst = max(worst, float(cost))
        return worst

    def footprintCost(self, footprint: Polygon) -> float:
        """Max cost along the closed polygon; LETHAL_OBSTACLE if any vertex is off the map."""
        points = list(footprint.points)
        if not points:
            raise ValueError("footprint has no points")
        cells = []
        for p in points:
            mx, my = self.worldToMapValidated(p.x, p.y)
            if mx is None or my is None:
                return float(LETHAL_OBSTACLE)
            cells.append((mx, my))
        if len(cells) == 1:
            return float(self.pointCost(*cells[0]))
        worst = 0.0
        for (ax, ay), (bx, by) in zip(cells, cells[1:] + cells[:1], strict=True):
            worst = max(worst, self.lineCost(ax, bx, ay, by))
            if worst == LETHAL_OBSTACLE:
                break
        return worst

    def footprintCostAtPose(self, x: float, y: float, theta: float, footprint: Polygon) -> float:
        """footprintCost of `footprint` (robot frame) placed at (x, y, theta) in the costmap's frame."""
        c, s = math.cos(theta), math.sin(theta)
        placed = Polygon(
            points=[Point32(x=float(x + p.x * c - p.y * s), y=float(y + p.x * s + p.y * c)) for p in footprint.points]
        )
        return self.footprintCost(placed)


def circle_footprint(radius: float, sides: int = 16) -> Polygon:
    """A polygon approximating a round robot (the TurtleBot 4's radius is robot.yaml's drive.radius)."""
    return Polygon(
        points=[
            Point32(x=radius * math.cos(2 * math.pi * i / sides), y=radius * math.sin(2 * math.pi * i / sides))
            for i in range(sides)
        ]
    )
