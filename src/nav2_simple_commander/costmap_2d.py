"""Upstream import path: `from nav2_simple_commander.costmap_2d import PyCostmap2D`."""

from tb4.navigator.costmap_2d import PyCostmap2D

__all__ = ["PyCostmap2D"]
