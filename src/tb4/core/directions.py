"""TurtleBot4Directions: compass headings in degrees on the map (north = +x, west = +y), as upstream defines them,
and the one parser of direction names that the navigator, the `tb4` command and the language vocabulary share."""

from __future__ import annotations

import math
from enum import IntEnum

__all__ = ["TurtleBot4Directions", "DIRECTIONS", "direction_from_name", "parse_heading"]


class TurtleBot4Directions(IntEnum):
    NORTH = 0
    NORTH_WEST = 45
    WEST = 90
    SOUTH_WEST = 135
    SOUTH = 180
    SOUTH_EAST = 225
    EAST = 270
    NORTH_EAST = 315


#: Member name -> degrees, for code that reads the table rather than the enum (the language vocabulary).
DIRECTIONS: dict[str, int] = {d.name: int(d) for d in TurtleBot4Directions}


def _key(name: str) -> str:
    return name.strip().upper().replace("-", "_").replace(" ", "_")


def direction_from_name(name: str) -> TurtleBot4Directions:
    """'north-west', 'NORTH_WEST', 'North West' -> NORTH_WEST; ValueError listing the valid names otherwise."""
    if not isinstance(name, str):
        raise TypeError(f"direction name must be a string, got {type(name).__name__}")
    try:
        return TurtleBot4Directions[_key(name)]
    except KeyError:
        valid = ", ".join(d.name for d in TurtleBot4Directions)
        raise ValueError(f"unknown direction {name!r}; use one of {valid} or a number of degrees") from None


def parse_heading(text: str) -> float:
    """Degrees (map-relative, 0 = north = +x, 90 = west) from a number or a direction name."""
    if _key(text) in DIRECTIONS:
        return float(DIRECTIONS[_key(text)])
    try:
        value = float(text)
    except ValueError:
        names = ", ".join(d.lower() for d in DIRECTIONS)
        raise ValueError(f"heading must be degrees or a direction ({names}), got {text!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"heading must be finite, got {text!r}")
    return value
