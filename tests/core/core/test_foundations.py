"""tb4.core: the one home of geometry, units, directions, robot parameters and bounded waits."""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

from tb4.core.directions import DIRECTIONS, TurtleBot4Directions, parse_heading
from tb4.core.geometry import (
    compose,
    euler_to_quaternion,
    inverse,
    quaternion_to_yaw,
    rewrap,
    same_pose,
    wrap_angle,
    yaw_to_quaternion,
)
from tb4.core.robot_params import default_robot_params, robot_radius
from tb4.core.units import from_sec_nanosec, seconds_of, to_sec_nanosec
from tb4.core.waits import Deadline, WaitTimeout, wait_for_future, wait_until


@pytest.mark.parametrize("yaw", [0.0, 0.5, -1.2, math.pi - 1e-9, 3.0])
def test_yaw_survives_the_quaternion_round_trip(yaw: float) -> None:
    q = yaw_to_quaternion(yaw)
    assert math.isclose(sum(v * v for v in q), 1.0)
    assert quaternion_to_yaw(*q) == pytest.approx(yaw)
    assert euler_to_quaternion(yaw=yaw) == pytest.approx(q)


@pytest.mark.parametrize("angle", [7.0, -0.1, math.pi, 1e6, 0.1 + 2 * math.pi])
def test_rewrap_is_wrap_angle_repeated_to_the_last_bit(angle: float) -> None:
    for times in (0, 1, 2, 50):
        expected = angle
        for _ in range(times):
            expected = wrap_angle(expected + 0.0)
        assert repr(rewrap(angle, times)) == repr(expected)


def test_wrap_angle_on_floats_and_arrays() -> None:
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle(math.pi) == pytest.approx(-math.pi)
    np.testing.assert_allclose(wrap_angle(np.array([0.0, 2 * math.pi + 0.1])), [0.0, 0.1], atol=1e-12)


def test_compose_with_the_inverse_is_the_identity() -> None:
    a = (1.0, -2.0, 0.7)
    assert compose(a, inverse(a)) == pytest.approx((0.0, 0.0, 0.0), abs=1e-12)
    assert compose((1.0, 2.0, math.pi / 2), (1.0, 0.0, 0.0))[:2] == pytest.approx((1.0, 3.0))


def test_same_pose_within_the_bounds_across_the_angle_wrap() -> None:
    assert same_pose((1.0, 2.0, 0.0), (1.1, 2.05, 0.05))
    assert same_pose((0.0, 0.0, math.pi - 0.02), (0.0, 0.0, -math.pi + 0.02))  # 0.04 rad apart, not 2 pi
    assert not same_pose((0.0, 0.0, 0.0), (0.2, 0.0, 0.0))
    assert not same_pose((0.0, 0.0, 0.0), (0.0, 0.0, 0.2))
    assert same_pose((0.0, 0.0, 0.0), (0.2, 0.0, 0.0), position=0.25)
    assert not same_pose((math.nan, 0.0, 0.0), (0.0, 0.0, 0.0))  # an estimate with NaN is no pose


def test_durations_split_and_join() -> None:
    assert to_sec_nanosec(1.25) == (1, 250_000_000)
    assert to_sec_nanosec(float("nan")) == (0, 0) and to_sec_nanosec(-3.0) == (0, 0)
    assert to_sec_nanosec(0.9999999999)[1] <= 999_999_999
    assert from_sec_nanosec(2, 500_000_000) == 2.5

    class Stamp:
        sec, nanosec = 3, 1

    assert seconds_of(Stamp()) == pytest.approx(3.000000001)


def test_directions_table_and_heading_parser_agree() -> None:
    assert {d.name: int(d) for d in TurtleBot4Directions} == DIRECTIONS
    assert parse_heading("south-west") == 135.0 and parse_heading("12.5") == 12.5
    with pytest.raises(ValueError, match="north_west"):
        parse_heading("up")
    with pytest.raises(ValueError, match="finite"):
        parse_heading("inf")


def test_the_robot_radius_has_one_source() -> None:
    from tb4.nav.costmap import CostmapParams
    from tb4.nav.params import default_nav2_params

    assert robot_radius() == default_robot_params().drive.radius
    assert CostmapParams().robot_radius == robot_radius()
    assert default_nav2_params().costmap_params("local").robot_radius == robot_radius()
    assert default_nav2_params().costmap_params("global").robot_radius == robot_radius()


def test_wait_until_returns_false_or_raises_naming_what() -> None:
    assert wait_until(lambda: True, 0.0)
    assert not wait_until(lambda: False, 0.05)
    with pytest.raises(WaitTimeout, match="the answer"):
        wait_until(lambda: False, 0.05, "the answer")
    with pytest.raises(ValueError):
        Deadline(float("nan"))


class _Future:
    def __init__(self) -> None:
        self._done, self._callbacks, self.value = False, [], None

    def done(self) -> bool:
        return self._done

    def add_done_callback(self, cb) -> None:  # type: ignore[no-untyped-def]
        self._callbacks.append(cb)

    def set_result(self, value: object) -> None:
        self.value, self._done = value, True
        for cb in self._callbacks:
            cb(self)

    def exception(self) -> None:
        return None

    def result(self) -> object:
        return self.value


def test_wait_for_future_returns_the_result_or_times_out_with_the_given_type() -> None:
    class Custom(WaitTimeout):
        pass

    future = _Future()
    threading.Timer(0.05, future.set_result, args=(42,)).start()
    assert wait_for_future(future, 5.0, "the result") == 42
    with pytest.raises(Custom, match="nothing"):
        wait_for_future(_Future(), 0.05, "nothing", Custom)


def test_navigator_timeout_is_the_one_wait_timeout() -> None:
    pytest.importorskip("rclpy")
    from tb4.navigator.timeouts import NavigatorTimeout

    assert issubclass(NavigatorTimeout, WaitTimeout) and issubclass(NavigatorTimeout, TimeoutError)
