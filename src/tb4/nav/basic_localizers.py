"""Localizers without a filter: dead reckoning from the initial pose, and ground truth for reference runs.

Both behave like AMCL as users see it: no map pose until an initial pose is given, and a wrong initial pose
gives a consistently wrong map pose. `Localizer` then trusts odometry (it drifts when odometry does; it never
reads the simulator's truth). `TruthLocalizer` is `tb4 sim --localization truth`: the map pose is the
simulator's true pose (shifted by the initial pose's error), the baseline AMCL is measured against.
The particle filter is tb4.nav.amcl.Amcl, with the same interface.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from tb4.core.geometry import Pose, compose, inverse, wrap_angle

__all__ = ["Localizer", "TruthLocalizer"]


class Localizer:
    """Holds map->odom. `set_initial_pose` is what a message on 'initialpose' does to AMCL."""

    def __init__(self, initial_cov_xx: float = 0.25, initial_cov_yy: float = 0.25, initial_cov_aa: float = 0.0685):
        self._map_to_odom: Pose | None = None
        self._cov_diag = (float(initial_cov_xx), float(initial_cov_yy), float(initial_cov_aa))
        self.last_update: float | None = None

    @property
    def is_localized(self) -> bool:
        return self._map_to_odom is not None

    def set_initial_pose(
        self, x: float, y: float, yaw: float, odom_pose: Pose, now: float = 0.0, cov: Any = None
    ) -> None:
        """The robot is at map pose (x, y, yaw) while odometry reads `odom_pose` (`cov` is not used here)."""
        for value in (x, y, yaw, *odom_pose):
            if not math.isfinite(value):
                raise ValueError(f"initial pose must be finite, got {(x, y, yaw)}")
        self._map_to_odom = compose((float(x), float(y), wrap_angle(float(yaw))), inverse(odom_pose))
        self.last_update = float(now)

    def reset(self) -> None:
        """Forget the pose (e.g. after a map change): the robot must be given an initial pose again."""
        self._map_to_odom = None
        self.last_update = None

    def map_to_odom(self) -> Pose | None:
        return self._map_to_odom

    def map_pose(self, odom_pose: Pose) -> Pose | None:
        """Map-frame pose for an odometry pose, or None when not localized."""
        if self._map_to_odom is None:
            return None
        return compose(self._map_to_odom, odom_pose)

    def covariance(self) -> list[float]:
        """Row-major 6x6 covariance (x, y, z, roll, pitch, yaw) for geometry_msgs/PoseWithCovariance."""
        cov = [0.0] * 36
        cov[0], cov[7], cov[35] = self._cov_diag
        return cov

    def covariance_matrix(self) -> list[list[float]]:
        """The same covariance as a 6x6 list of rows."""
        flat = self.covariance()
        return [flat[i * 6 : i * 6 + 6] for i in range(6)]

    def update(self, odom_pose: Pose, scan: Any, now: float) -> bool:
        """Scans change nothing: odometry is trusted."""
        return False


class TruthLocalizer(Localizer):
    """Map pose = the simulator's true pose, offset by the initial pose's error (zero for a right initial pose)."""

    def __init__(
        self,
        truth_fn: Callable[[], Pose],
        odom_fn: Callable[[], Pose],
        initial_cov_xx: float = 0.25,
        initial_cov_yy: float = 0.25,
        initial_cov_aa: float = 0.0685,
    ) -> None:
        super().__init__(initial_cov_xx, initial_cov_yy, initial_cov_aa)
        self._truth_fn = truth_fn
        self._odom_fn = odom_fn
        self._offset: Pose | None = None

    def set_initial_pose(
        self, x: float, y: float, yaw: float, odom_pose: Pose, now: float = 0.0, cov: Any = None
    ) -> None:
        super().set_initial_pose(x, y, yaw, odom_pose, now)
        given = (float(x), float(y), wrap_angle(float(yaw)))
        self._offset = compose(given, inverse(self._truth_fn()))

    def reset(self) -> None:
        super().reset()
        self._offset = None

    def map_to_odom(self) -> Pose | None:
        if self._offset is None:
            return None
        return compose(compose(self._offset, self._truth_fn()), inverse(self._odom_fn()))

    def map_pose(self, odom_pose: Pose) -> Pose | None:
        m2o = self.map_to_odom()
        return None if m2o is None else compose(m2o, odom_pose)

    def update(self, odom_pose: Pose, scan: Any, now: float) -> bool:
        self.last_update = float(now) if self._offset is not None else None
        return False
