"""Which localizer the navigation core runs: `tb4 sim --localization amcl|truth|odometry`, built from nav2.yaml."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from tb4.core.geometry import Pose
from tb4.core.maps import OccupancyMap
from tb4.nav.amcl import Amcl, AmclParams
from tb4.nav.basic_localizers import Localizer, TruthLocalizer
from tb4.nav.params import Nav2Params

__all__ = ["LOCALIZATION_MODES", "make_localizer"]

# amcl: the particle filter; truth: the simulator's true pose; odometry: dead reckoning from the initial pose
LOCALIZATION_MODES = ("amcl", "truth", "odometry")


def make_localizer(
    kind: str, grid: OccupancyMap, params: Nav2Params, robot: Any, odom_fn: Callable[[], Pose], seed: int = 0
) -> Localizer | Amcl:
    """The localizer for `kind`; ValueError naming the choices for anything else."""
    amcl = params.amcl
    cov = (amcl["initial_cov_xx"], amcl["initial_cov_yy"], amcl["initial_cov_aa"])
    if kind == "amcl":
        return Amcl(grid, AmclParams.from_section(amcl), seed=seed)
    if kind == "truth":
        if robot is None or not hasattr(robot, "pose"):
            raise ValueError("truth localization needs a robot that reports its true pose")

        def truth() -> Pose:
            p = robot.pose()
            return (float(p.x), float(p.y), float(p.yaw))

        return TruthLocalizer(truth, odom_fn, *cov)
    if kind == "odometry":
        return Localizer(*cov)
    raise ValueError(f"localization must be one of {', '.join(LOCALIZATION_MODES)}, got {kind!r}")
