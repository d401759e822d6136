"""TurtleBot4Directions: upstream values and parsing of direction names."""

from __future__ import annotations

import pytest

pytest.importorskip("rclpy", reason="ROS wheels not installed")

from tb4.core.directions import direction_from_name  # noqa: E402
from tb4.navigator import TurtleBot4Directions  # noqa: E402
from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions as Upstream  # noqa: E402


def test_upstream_values() -> None:
    expected = {
        "NORTH": 0, "NORTH_WEST": 45, "WEST": 90, "SOUTH_WEST": 135,
        "SOUTH": 180, "SOUTH_EAST": 225, "EAST": 270, "NORTH_EAST": 315,
    }  # fmt: skip
    assert {d.name: int(d) for d in TurtleBot4Directions} == expected
    assert Upstream is TurtleBot4Directions


def test_names_parse_and_unknown_names_fail_clearly() -> None:
    assert direction_from_name("north-west") is TurtleBot4Directions.NORTH_WEST
    assert direction_from_name(" East ") is TurtleBot4Directions.EAST
    with pytest.raises(ValueError, match="NORTH_EAST"):
        direction_from_name("up")
    with pytest.raises(TypeError):
        direction_from_name(90)  # type: ignore[arg-type]
