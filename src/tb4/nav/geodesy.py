"""GPS <-> map conversion on a local tangent plane, the way robot_localization's navsat_transform does it.

A world names its *datum*: the latitude and longitude of the map origin and the heading of the map's +x axis
(degrees counter-clockwise from east, robot_localization's datum yaw). Geodetic points go WGS84 -> ECEF ->
east/north/up at the datum (GeographicLib's LocalCartesian, `use_local_cartesian: true`), then rotate by the
datum heading into the map frame. Orientations are not converted: Nav2's waypoint follower copies a GeoPose's
orientation into the map pose unchanged, and so do we.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Datum", "GeodesyError", "check_geopoint", "WGS84_A", "WGS84_F"]

WGS84_A = 6378137.0  # m, semi-major axis
WGS84_F = 1.0 / 298.257223563  # flattening
_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared


class GeodesyError(ValueError):
    """A geodetic point that cannot be converted (not finite, latitude beyond the poles, ...)."""


def _ecef(lat_deg: float, lon_deg: float, alt: float) -> tuple[float, float, float]:
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    sin_lat, cos_lat = math.sin(lat), math.cos(lat)
    n = WGS84_A / math.sqrt(1.0 - _E2 * sin_lat * sin_lat)
    return (
        (n + alt) * cos_lat * math.cos(lon),
        (n + alt) * cos_lat * math.sin(lon),
        (n * (1.0 - _E2) + alt) * sin_lat,
    )


def _geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """ECEF -> (lat deg, lon deg, alt m) by Bowring's iteration (sub-millimetre after a few rounds)."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1.0 - _E2))
    alt = 0.0
    for _ in range(8):
        sin_lat = math.sin(lat)
        n = WGS84_A / math.sqrt(1.0 - _E2 * sin_lat * sin_lat)
        alt = p / math.cos(lat) - n if abs(math.cos(lat)) > 1e-12 else abs(z) - n * (1.0 - _E2)
        lat = math.atan2(z, p * (1.0 - _E2 * n / (n + alt)))
    return math.degrees(lat), math.degrees(lon), alt


def check_geopoint(lat: float, lon: float, alt: float = 0.0) -> None:
    """Refuse what no GPS can report: non-finite numbers, |lat| > 90, |lon| > 180."""
    for name, value in (("latitude", lat), ("longitude", lon), ("altitude", alt)):
        if not math.isfinite(value):
            raise GeodesyError(f"{name} must be finite, got {value}")
    if abs(lat) > 90.0:
        raise GeodesyError(f"latitude must be within [-90, 90] degrees, got {lat}")
    if abs(lon) > 180.0:
        raise GeodesyError(f"longitude must be within [-180, 180] degrees, got {lon}")


@dataclass(frozen=True)
class Datum:
    """The geodetic pose of the map origin: latitude, longitude (degrees), heading of map +x (deg from east)."""

    latitude: float
    longitude: float
    heading: float = 0.0
    altitude: float = 0.0

    def __post_init__(self) -> None:
        check_geopoint(self.latitude, self.longitude, self.altitude)
        if not math.isfinite(self.heading):
            raise GeodesyError(f"datum heading must be finite, got {self.heading}")
        if abs(self.latitude) > 89.9:
            raise GeodesyError("a datum at a pole has no east/north: use a latitude within +-89.9 degrees")

    def _frame(self) -> tuple[tuple[float, float, float], tuple[float, ...]]:
        lat, lon = math.radians(self.latitude), math.radians(self.longitude)
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        # rows: east, north, up unit vectors in ECEF
        rows = (-so, co, 0.0, -sl * co, -sl * so, cl, cl * co, cl * so, sl)
        return _ecef(self.latitude, self.longitude, self.altitude), rows

    def to_enu(self, lat: float, lon: float, alt: float = 0.0) -> tuple[float, float, float]:
        """East, north, up (m) of a geodetic point relative to the datum."""
        check_geopoint(lat, lon, alt)
        origin, r = self._frame()
        x, y, z = _ecef(lat, lon, alt)
        dx, dy, dz = x - origin[0], y - origin[1], z - origin[2]
        return (
            r[0] * dx + r[1] * dy + r[2] * dz,
            r[3] * dx + r[4] * dy + r[5] * dz,
            r[6] * dx + r[7] * dy + r[8] * dz,
        )

    def from_enu(self, east: float, north: float, up: float = 0.0) -> tuple[float, float, float]:
        """(lat, lon, alt) of a point given in east/north/up metres from the datum."""
        origin, r = self._frame()
        x = origin[0] + r[0] * east + r[3] * north + r[6] * up
        y = origin[1] + r[1] * east + r[4] * north + r[7] * up
        z = origin[2] + r[2] * east + r[5] * north + r[8] * up
        return _geodetic(x, y, z)

    def to_map(self, lat: float, lon: float, alt: float = 0.0) -> tuple[float, float]:
        """Map-frame (x, y) of a geodetic point (what navsat_transform's fromLL service answers)."""
        east, north, _ = self.to_enu(lat, lon, alt)
        h = math.radians(self.heading)
        c, s = math.cos(h), math.sin(h)
        return (c * east + s * north, -s * east + c * north)

    def from_map(self, x: float, y: float, up: float = 0.0) -> tuple[float, float, float]:
        """(lat, lon, alt) of a map-frame point (toLL), e.g. for publishing NavSatFix from the true pose."""
        h = math.radians(self.heading)
        c, s = math.cos(h), math.sin(h)
        return self.from_enu(c * x - s * y, s * x + c * y, up)
