"""AMCL: Nav2's adaptive Monte Carlo localization on the lidar and odometry, in the navigation core (no ROS).

It has the Localizer's interface (tb4.nav.basic_localizers), so the rest of the stack does not care which one runs:
an initial pose (or global localization) seeds the particle filter; every scan is offered to `update`, which
runs a filter update only after the odometry moved update_min_d / update_min_a since the last one (or when one
is forced: first scan after an initial pose, `request_nomotion_update`). Each update applies the motion model
to the odometry step, weighs the particles by the laser model, resamples every resample_interval updates and
sets map->odom so that the best cluster's mean is where odometry says the robot is. Between updates map->odom
stays fixed, as in Nav2. Parameters are the amcl section of nav2.yaml (Nav2's names and defaults).
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from tb4.core.geometry import Pose, compose, inverse, wrap_angle
from tb4.core.maps import OccupancyMap
from tb4.nav.amcl_models import LikelihoodField, free_cells, sample_motion
from tb4.nav.basic_localizers import Localizer
from tb4.nav.particle_filter import ParticleFilter, PoseEstimate

__all__ = ["AmclParams", "Amcl"]

# (id(grid), laser parameters) -> (grid ref, likelihood field, free cells): the robots of a fleet localize on the
# same map object, so they share these read-only arrays (~50 MB each on the warehouse map) instead of one per robot
_MAP_MODELS: dict[tuple[int, tuple[float, ...]], tuple[weakref.ref, LikelihoodField, np.ndarray]] = {}


@dataclass(frozen=True)
class AmclParams:
    """The amcl node's parameters the filter reads (Nav2 names; defaults in nav2.yaml)."""

    alpha1: float = 0.2
    alpha2: float = 0.2
    alpha3: float = 0.2
    alpha4: float = 0.2
    alpha5: float = 0.2  # used by the omni model only; kept for a faithful parameter surface
    laser_likelihood_max_dist: float = 2.0
    laser_max_range: float = 100.0
    laser_min_range: float = -1.0
    max_beams: int = 60
    max_particles: int = 2000
    min_particles: int = 500
    pf_err: float = 0.05
    pf_z: float = 0.99
    recovery_alpha_fast: float = 0.0
    recovery_alpha_slow: float = 0.0
    resample_interval: int = 1
    sigma_hit: float = 0.2
    update_min_a: float = 0.2
    update_min_d: float = 0.25
    z_hit: float = 0.5
    z_rand: float = 0.5
    initial_cov_xx: float = 0.25
    initial_cov_yy: float = 0.25
    initial_cov_aa: float = 0.0685

    @classmethod
    def from_section(cls, section: Mapping[str, Any]) -> AmclParams:
        """From the amcl ros__parameters mapping (unknown keys there, e.g. z_short, are Nav2's and ignored)."""
        values: dict[str, Any] = {}
        for f in fields(cls):
            if f.name in section:
                values[f.name] = int(section[f.name]) if f.type in ("int", int) else float(section[f.name])
        p = cls(**values)
        p.check()
        return p

    def check(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise ValueError(f"amcl {f.name} must be finite, got {v}")
        if self.min_particles < 1 or self.max_particles < self.min_particles:
            raise ValueError("amcl needs 1 <= min_particles <= max_particles")
        if self.resample_interval < 1:
            raise ValueError(f"amcl resample_interval must be >= 1, got {self.resample_interval}")
        if min(self.alpha1, self.alpha2, self.alpha3, self.alpha4, self.update_min_d, self.update_min_a) < 0.0:
            raise ValueError("amcl alpha1..alpha4, update_min_d and update_min_a must be >= 0")


class Amcl(Localizer):
    """The filter plus its update policy; see the module docstring. `rng` makes a run reproducible. A Localizer:
    map->odom, map_pose and the covariance matrix work as for dead reckoning; the filter moves map->odom."""

    def __init__(self, grid: OccupancyMap, params: AmclParams | None = None, seed: int = 0) -> None:
        self.params = params or AmclParams()
        self.params.check()
        super().__init__(self.params.initial_cov_xx, self.params.initial_cov_yy, self.params.initial_cov_aa)
        self.rng = np.random.default_rng(seed)
        self.updates = 0
        self._estimate: PoseEstimate | None = None
        self._last_odom: Pose | None = None
        self._force = False
        self._resample_count = 0
        p = self.params
        self.pf = ParticleFilter(
            p.min_particles,
            p.max_particles,
            p.pf_err,
            p.pf_z,
            p.recovery_alpha_slow,
            p.recovery_alpha_fast,
            self._sample_free,
            self.rng,
        )
        self.set_map(grid)

    # --- map ------------------------------------------------------------------------------------------------
    def set_map(self, grid: OccupancyMap) -> None:
        """A new map: new likelihood field and free space; the particles are kept (same map frame)."""
        self.grid = grid
        self.field, self._free = _map_model(grid, self.params)

    def _sample_free(self, n: int, rng: np.random.Generator) -> np.ndarray:
        g = self.grid
        if len(self._free) == 0:
            raise ValueError("the map has no free cell to place a particle in")
        rows, cols = np.divmod(self._free[rng.integers(0, len(self._free), n)], g.data.shape[1])
        out = np.empty((n, 3))
        out[:, 0] = g.origin_x + (cols + rng.random(n)) * g.resolution
        out[:, 1] = g.origin_y + (rows + rng.random(n)) * g.resolution
        out[:, 2] = rng.uniform(-math.pi, math.pi, n)
        return out

    # --- the Localizer interface -------------------------------------------------------------------------
    def set_initial_pose(
        self, x: float, y: float, yaw: float, odom_pose: Pose, now: float = 0.0, cov: np.ndarray | None = None
    ) -> None:
        """Seed the filter around (x, y, yaw) with `cov` (3x3 x/y/yaw; default initial_cov_*), as 'initialpose'."""
        for value in (x, y, yaw, *odom_pose):
            if not math.isfinite(value):
                raise ValueError(f"initial pose must be finite, got {(x, y, yaw)}")
        p = self.params
        c = np.diag([p.initial_cov_xx, p.initial_cov_yy, p.initial_cov_aa]) if cov is None else np.asarray(cov, float)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise ValueError("initial pose covariance must be a finite 3x3 matrix (x, y, yaw)")
        if np.any(np.linalg.eigvalsh(0.5 * (c + c.T)) < -1e-9):
            raise ValueError("initial pose covariance must be positive semi-definite")
        yaw = wrap_angle(float(yaw))
        self.pf.init_gaussian((float(x), float(y), yaw), c)
        self._start(odom_pose, now, (float(x), float(y), yaw))

    def global_localization(self, odom_pose: Pose, now: float = 0.0) -> None:
        """reinitialize_global_localization: particles spread over all free space; the next scan updates."""
        self.pf.init_uniform()
        est = self.pf.estimate()
        self._start(odom_pose, now, est.pose)

    def _start(self, odom_pose: Pose, now: float, pose: Pose) -> None:
        self._estimate = self.pf.estimate()
        self._map_to_odom = compose(pose, inverse(odom_pose))
        self._last_odom = tuple(float(v) for v in odom_pose)  # type: ignore[assignment]
        self._force = True
        self._resample_count = 0
        self.last_update = float(now)

    def request_nomotion_update(self) -> None:
        """request_nomotion_update: run a filter update on the next scan even without motion."""
        self._force = True

    def reset(self) -> None:
        super().reset()
        self._estimate = None
        self._last_odom = None

    def covariance(self) -> list[float]:
        """Row-major 6x6 covariance (x, y, z, roll, pitch, yaw) of the estimate, for PoseWithCovariance."""
        out = [0.0] * 36
        if self._estimate is None:
            return out
        c = self._estimate.cov
        out[0], out[1], out[6], out[7] = float(c[0, 0]), float(c[0, 1]), float(c[1, 0]), float(c[1, 1])
        out[35] = float(c[2, 2])
        return out

    @property
    def estimate(self) -> PoseEstimate | None:
        return self._estimate

    def particles(self) -> tuple[np.ndarray, np.ndarray]:
        """(poses Nx3, weights N): what nav2_msgs/ParticleCloud carries."""
        return (self.pf.poses.copy(), self.pf.weights.copy())

    # --- the filter update -------------------------------------------------------------------------------
    def _moved(self, odom_pose: Pose) -> bool:
        old = self._last_odom
        assert old is not None
        p = self.params
        dx, dy = odom_pose[0] - old[0], odom_pose[1] - old[1]
        da = wrap_angle(odom_pose[2] - old[2])
        return abs(dx) > p.update_min_d or abs(dy) > p.update_min_d or abs(da) > p.update_min_a

    def wants_update(self, odom_pose: Pose) -> bool:
        """Would a scan at `odom_pose` run a filter update (moved past update_min_d / update_min_a, or forced)?"""
        return self._last_odom is not None and (self._force or self._moved(odom_pose))

    def update(self, odom_pose: Pose, scan: Any, now: float) -> bool:
        """Offer a scan taken at odometry pose `odom_pose`; True when it ran a filter update."""
        if self._last_odom is None:
            return False
        old = self._last_odom
        p = self.params
        moved = self._moved(odom_pose)
        if not (moved or self._force):
            return False
        if moved:
            sample_motion(self.pf.poses, old, odom_pose, (p.alpha1, p.alpha2, p.alpha3, p.alpha4), self.rng)
        bx, by, range_max = self.field.beams(
            scan.ranges, scan.angle_min, scan.angle_increment, scan.range_min, scan.range_max
        )
        self.pf.apply_likelihoods(self.field.likelihoods(self.pf.poses, bx, by, range_max))
        self._resample_count += 1
        est = self.pf.estimate()  # before resampling, from the weighted set (as Nav2 does)
        if self._resample_count % p.resample_interval == 0:
            self.pf.resample()
        self._estimate = est
        self._map_to_odom = compose(est.pose, inverse(odom_pose))
        self._last_odom = (float(odom_pose[0]), float(odom_pose[1]), float(odom_pose[2]))
        self._force = False
        self.last_update = float(now)
        self.updates += 1
        return True


def _map_model(grid: OccupancyMap, p: AmclParams) -> tuple[LikelihoodField, np.ndarray]:
    """The likelihood field and free cells of `grid` for these laser parameters, built once per map object
    (both are only read after they are built; the entry goes when the map does)."""
    laser = (p.z_hit, p.z_rand, p.sigma_hit, p.laser_likelihood_max_dist, p.max_beams, p.laser_max_range)
    key = (id(grid), (*laser, p.laser_min_range))
    cached = _MAP_MODELS.get(key)
    if cached is not None and cached[0]() is grid:
        return cached[1], cached[2]
    field = LikelihoodField(grid, *laser, p.laser_min_range)
    free = free_cells(grid)
    # the callback holds the dict itself: at interpreter exit the module's globals may already be gone
    models = _MAP_MODELS
    _MAP_MODELS[key] = (weakref.ref(grid, lambda _ref: models.pop(key, None)), field, free)
    return field, free
