"""GPS <-> map on a local tangent plane: known distances, round trips, the datum heading, hostile input."""

from __future__ import annotations

import math

import pytest

from tb4.nav.geodesy import Datum, GeodesyError

pytestmark = pytest.mark.core


def test_metres_per_degree_match_wgs84() -> None:
    d = Datum(45.0, 10.0, 0.0)
    east, north = d.to_map(45.0, 10.001)  # heading 0: map +x is east
    assert east == pytest.approx(78.85, abs=0.05) and abs(north) < 0.01  # 1e-3 deg lon at 45 deg N
    east, north = d.to_map(45.001, 10.0)
    assert north == pytest.approx(111.13, abs=0.05) and abs(east) < 0.01


@pytest.mark.parametrize("heading", [0.0, 90.0, -90.0, 30.0, 180.0])
def test_datum_heading_rotates_the_map(heading: float) -> None:
    d = Datum(48.1374, 11.5755, heading)
    x, y = d.to_map(*d.from_map(10.0, 0.0)[:2])
    assert (x, y) == pytest.approx((10.0, 0.0), abs=1e-6)
    lat, lon, _ = d.from_map(10.0, 0.0)  # 10 m along map +x, which points `heading` deg from east
    east, north, _ = d.to_enu(lat, lon)
    assert east == pytest.approx(10 * math.cos(math.radians(heading)), abs=1e-6)
    assert north == pytest.approx(10 * math.sin(math.radians(heading)), abs=1e-6)


def test_round_trips_over_a_few_kilometres() -> None:
    d = Datum(-33.86, 151.21, 17.0)
    for x, y in [(0.0, 0.0), (3.3, -7.1), (2500.0, -1800.0)]:
        lat, lon, alt = d.from_map(x, y)
        assert d.to_map(lat, lon, alt) == pytest.approx((x, y), abs=1e-5)
    assert d.to_map(-33.86, 151.21) == pytest.approx((0.0, 0.0), abs=1e-9)


@pytest.mark.parametrize(
    "point", [(math.nan, 0.0), (0.0, math.inf), (91.0, 0.0), (-90.5, 0.0), (0.0, 180.5), (0.0, -999.0)]
)
def test_impossible_points_are_refused(point: tuple[float, float]) -> None:
    with pytest.raises(GeodesyError):
        Datum(45.0, 10.0).to_map(*point)


def test_bad_datums_are_refused() -> None:
    for args in [(math.nan, 0.0, 0.0), (90.0, 0.0, 0.0), (0.0, 0.0, math.inf), (0.0, 200.0, 0.0)]:
        with pytest.raises(GeodesyError):
            Datum(*args)
