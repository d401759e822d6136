"""Upstream import path: `from nav2_simple_commander.footprint_collision_checker import FootprintCollisionChecker`."""

from tb4.navigator.footprint_collision_checker import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    MAX_NON_OBSTACLE,
    NO_INFORMATION,
    FootprintCollisionChecker,
)

__all__ = [
    "FootprintCollisionChecker",
    "NO_INFORMATION",
    "LETHAL_OBSTACLE",
    "INSCRIBED_INFLATED_OBSTACLE",
    "MAX_NON_OBSTACLE",
    "FREE_SPACE",
]
