"""The AMCL-like localizer: no pose before an initial pose, then map->odom from it (right or wrong)."""

from __future__ import annotations

import math

import pytest

from tb4.core.geometry import compose, inverse
from tb4.nav.basic_localizers import Localizer

pytestmark = pytest.mark.core


def test_compose_inverse_roundtrip():
    a = (1.0, -2.0, 0.7)
    b = (0.3, 0.4, -1.2)
    c = compose(compose(a, b), inverse(b))
    assert all(abs(u - v) < 1e-12 for u, v in zip(c, a, strict=True))
    ident = compose(a, inverse(a))
    assert all(abs(v) < 1e-12 for v in ident)


def test_not_localized_until_initial_pose():
    loc = Localizer()
    assert not loc.is_localized
    assert loc.map_pose((0.0, 0.0, 0.0)) is None
    assert loc.map_to_odom() is None


def test_map_pose_follows_odometry_after_initial_pose():
    loc = Localizer()
    odom_now = (0.5, 0.0, math.pi / 2)
    loc.set_initial_pose(2.0, 3.0, 0.0, odom_now)
    p = loc.map_pose(odom_now)
    assert p == pytest.approx((2.0, 3.0, 0.0), abs=1e-12)
    # the robot drives 1 m forward in odom (along odom +y, its heading): 1 m along map +x
    p2 = loc.map_pose((0.5, 1.0, math.pi / 2))
    assert p2 == pytest.approx((3.0, 3.0, 0.0), abs=1e-12)


def test_wrong_initial_pose_gives_consistently_wrong_map_pose():
    loc = Localizer()
    loc.set_initial_pose(1.0, 0.0, 0.0, (0.0, 0.0, 0.0))  # truth is (0, 0, 0)
    assert loc.map_pose((2.0, 0.0, 0.0)) == pytest.approx((3.0, 0.0, 0.0))


def test_covariance_and_reset():
    loc = Localizer(0.25, 0.36, 0.07)
    cov = loc.covariance()
    assert len(cov) == 36 and cov[0] == 0.25 and cov[7] == 0.36 and cov[35] == 0.07
    assert len(loc.covariance_matrix()) == 6 and loc.covariance_matrix()[5][5] == 0.07
    loc.set_initial_pose(0.0, 0.0, 0.0, (0.0, 0.0, 0.0))
    loc.reset()
    assert not loc.is_localized


def test_non_finite_initial_pose_rejected():
    with pytest.raises(ValueError):
        Localizer().set_initial_pose(float("nan"), 0.0, 0.0, (0.0, 0.0, 0.0))
