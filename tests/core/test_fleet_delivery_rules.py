"""fleet_delivery's coordination rules, without ROS: the nearest free robot takes a delivery, goals are kept
SPACING apart, busy robots take nothing."""

from __future__ import annotations

import pytest

from tb4.tutorials.fleet_delivery import SPACING, Courier, assign

pytestmark = pytest.mark.core


def courier(name: str, at: tuple[float, float], busy: tuple[float, float] | None = None) -> Courier:
    job = ("job", busy, "NORTH") if busy is not None else None
    return Courier(name, navigator=None, dock=(0.0, 0.0, 0.0), at=at, job=job)  # type: ignore[arg-type]


def test_nearest_free_robot_takes_each_delivery_in_order() -> None:
    a, b = courier("/robot1", (0.0, 0.0)), courier("/robot2", (10.0, 0.0))
    far, near = ("far", (9.0, 5.0), "EAST"), ("near", (1.0, 5.0), "WEST")
    pairs = assign([far, near], [a, b])
    assert [(c.namespace, d[0]) for c, d in pairs] == [("/robot2", "far"), ("/robot1", "near")]


def test_busy_robots_take_nothing() -> None:
    a = courier("/robot1", (0.0, 0.0), busy=(20.0, 20.0))
    b = courier("/robot2", (10.0, 0.0))
    pairs = assign([("x", (0.0, 5.0), "EAST")], [a, b])
    assert [(c.namespace, d[0]) for c, d in pairs] == [("/robot2", "x")]
    assert assign([("x", (0.0, 5.0), "EAST")], [a]) == []


def test_a_delivery_next_to_another_robots_goal_waits_until_it_arrived() -> None:
    a = courier("/robot1", (0.0, 0.0), busy=(5.0, 5.0))
    b = courier("/robot2", (-10.0, 0.0))
    c = courier("/robot3", (20.0, 20.0))
    by_a = ("by a's goal", (5.0 + 0.5 * SPACING, 5.0), "EAST")
    apart = ("apart", (-10.0, 8.0), "EAST")
    next_to_apart = ("next to apart", (-10.0 + 0.5 * SPACING, 8.0), "EAST")
    pairs = assign([by_a, apart, next_to_apart], [a, b, c])
    assert [(x.namespace, d[0]) for x, d in pairs] == [("/robot2", "apart")]
    a.job, a.at = None, (5.0, 5.0)  # a arrived: free again, nobody is driving near its goal
    pairs = assign([by_a], [a, c])
    assert [(x.namespace, d[0]) for x, d in pairs] == [("/robot1", "by a's goal")]
