"""TurtleBot4Directions: compass headings in degrees on the map (north = +x, west = +y), as upstream defines them."""

from __future__ import annotations

from enum import IntEnum

__all__ = ["TurtleBot4Directions", "direction_from_name"]


class TurtleBot4Directions(IntEnum):
    NORTH = 0
    NORTH_WEST = 45
    WEST = 90
    SOUTH_WEST = 135
    SOUTH = 180
    SOUTH_EAST = 225
    EAST = 270
    NORTH_EAST = 315


def direction_from_name(name: str) -> TurtleBot4Directions:
    """'north-west', 'NORTH_WEST', 'North West' -> NORTH_WEST; ValueError listing the valid names otherwise."""
    if not isinstance(name, str):
        raise TypeError(f"direction name must be a string, got {type(name).__name__}")
    key = name.strip().upper().replace("-", "_").replace(" ", "_")
    try:
        return TurtleBot4Directions[key]
    except KeyError:
        valid = ", ".join(d.name for d in TurtleBot4Directions)
        raise ValueError(f"unknown direction {name!r}; use one of {valid} or a number of degrees") from None
