"""Which middleware an environment holds (tb4.rosenv, `tb4 doctor`): the distribution read off rclpy's version, and
a half-installed or mixed environment named for what it is, with the install command that repairs it."""

from __future__ import annotations

import pytest

from tb4.rosenv import Middleware, middleware_problems

pytestmark = pytest.mark.core


def test_one_distributions_middleware_is_whole() -> None:
    jazzy = Middleware("7.1.6", "8.4.3", "2.14.5", "jazzy", "jazzy")
    kilted = Middleware("9.1.2", "9.3.3", "3.2.3", "", "kilted")
    assert middleware_problems(jazzy) == [] and middleware_problems(kilted) == []
    assert jazzy.describe() == "ROS 2 Jazzy (rclpy 7.1.6, rmw_fastrtps_cpp 8.4.3, Fast DDS 2.14.5)"


def test_a_mixed_or_half_installed_environment_says_what_is_wrong() -> None:
    mixed = middleware_problems(Middleware("7.1.6", "9.3.3", "3.2.3", "jazzy", "jazzy"))
    assert len(mixed) == 2 and all("mixes two distributions" in p for p in mixed), mixed
    assert "rmw_fastrtps_cpp 9.3.3 is not ROS 2 Jazzy's" in mixed[0]
    # made for Jazzy, but its ROS wheels never arrived (an install stopped half way)
    (half,) = middleware_problems(Middleware("", "", "", "jazzy", ""))
    assert half == "this environment was made for ROS 2 Jazzy but holds no rclpy"
    (other,) = middleware_problems(Middleware("9.1.2", "9.3.3", "3.2.3", "jazzy", "kilted"))
    assert other == "this environment was made for ROS 2 Jazzy but holds rclpy 9.1.2"
    assert Middleware("", "", "", "", "").describe().startswith("ROS 2 unknown (rclpy missing")
