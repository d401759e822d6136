"""LineIterator: upstream stepping (along x, or y when vertical), validation, float length."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("geometry_msgs.msg", reason="ROS wheels not installed")

from tb4.navigator import LineIterator  # noqa: E402


def walk(it: LineIterator) -> list[tuple[float, float]]:
    points = []
    while it.isValid():
        points.append((it.getX(), it.getY()))
        it.advance()
        assert len(points) < 1000
    return points


def test_diagonal_steps_along_x_to_the_end() -> None:
    points = walk(LineIterator(0, 0, 2, 1, 0.5))
    assert points[0] == (0, 0) and points[-1] == (2, 1)
    assert [x for x, _ in points] == [0, 0.5, 1.0, 1.5, 2.0]
    assert all(y == pytest.approx(x / 2) for x, y in points)


def test_backwards_and_vertical_lines() -> None:
    assert walk(LineIterator(3, 0, 1, 0, 1.0)) == [(3, 0), (2, 0), (1, 0)]
    assert walk(LineIterator(1, 4, 1, 2, 1.0)) == [(1, 4), (1, 3), (1, 2)]


def test_endpoints_length_and_validation() -> None:
    it = LineIterator(0, 0, 3, 4)
    assert (it.getX0(), it.getY0(), it.getX1(), it.getY1()) == (0, 0, 3, 4)
    length = it.get_line_length()
    assert isinstance(length, float) and length == pytest.approx(5.0)
    with pytest.raises(ValueError, match="zero length"):
        LineIterator(1, 1, 1, 1)
    with pytest.raises(ValueError, match="positive"):
        LineIterator(0, 0, 1, 1, 0)
    with pytest.raises(TypeError):
        LineIterator("0", 0, 1, 1)
    with pytest.raises(ValueError):
        LineIterator(0, math.nan, 1, 1)
