"""AMCL's two models, vectorised over all particles: Nav2's differential motion model and likelihood-field laser model.

Motion (nav2_amcl DifferentialMotionModel, Thrun et al. "sample_motion_model_odometry"): an odometry step is
split into rotate (rot1), translate (trans), rotate (rot2); each part gets zero-mean Gaussian noise whose variance
grows with alpha1 (rotation from rotation), alpha2 (rotation from translation), alpha3 (translation from
translation) and alpha4 (translation from rotation). Rotations are measured the short way round, so driving
backwards is not mistaken for a half turn.

Laser (nav2_amcl LikelihoodFieldModel): each used beam's end point is looked up in the distance to the nearest
occupied cell (capped at laser_likelihood_max_dist; off the map it counts as that cap); a beam contributes
pz = z_hit * exp(-d^2 / (2 sigma_hit^2)) + z_rand / range_max and a particle's likelihood is 1 + sum(pz^3),
Nav2's ad-hoc but robust combination. Beams at or beyond range_max (nothing seen) and non-finite ones are skipped.
"""

from __future__ import annotations

import math

import numpy as np

from tb4.core.distance import distance_to_marked
from tb4.core.geometry import wrap_angle
from tb4.core.maps import OccupancyMap

__all__ = ["sample_motion", "LikelihoodField", "free_cells"]


def sample_motion(
    poses: np.ndarray,
    old_odom: tuple[float, float, float],
    new_odom: tuple[float, float, float],
    alphas: tuple[float, float, float, float],
    rng: np.random.Generator,
) -> None:
    """Move every particle (in place) by the odometry step old_odom -> new_odom with the model's noise."""
    a1, a2, a3, a4 = alphas
    dx = new_odom[0] - old_odom[0]
    dy = new_odom[1] - old_odom[1]
    dyaw = wrap_angle(new_odom[2] - old_odom[2])
    trans = math.hypot(dx, dy)
    rot1 = 0.0 if trans < 0.01 else float(wrap_angle(math.atan2(dy, dx) - old_odom[2]))  # in-place turns
    rot2 = float(wrap_angle(dyaw - rot1))
    rot1_n = min(abs(float(wrap_angle(rot1))), abs(float(wrap_angle(rot1 - math.pi))))
    rot2_n = min(abs(float(wrap_angle(rot2))), abs(float(wrap_angle(rot2 - math.pi))))
    n = len(poses)
    z = rng.standard_normal((n, 3))
    rot1_hat = rot1 - z[:, 0] * math.sqrt(a1 * rot1_n**2 + a2 * trans**2)
    trans_hat = trans - z[:, 1] * math.sqrt(a3 * trans**2 + a4 * rot1_n**2 + a4 * rot2_n**2)
    rot2_hat = rot2 - z[:, 2] * math.sqrt(a1 * rot2_n**2 + a2 * trans**2)
    heading = poses[:, 2] + rot1_hat
    poses[:, 0] += trans_hat * np.cos(heading)
    poses[:, 1] += trans_hat * np.sin(heading)
    poses[:, 2] = wrap_angle(heading + rot2_hat)


def _touching(cells: np.ndarray) -> np.ndarray:
    """Cells that are in `cells` or one of their 8 neighbours (a 3 x 3 binary dilation, nothing beyond the edge)."""
    height, width = cells.shape
    padded = np.pad(cells, 1)
    out = np.zeros_like(cells)
    for dr in range(3):
        for dc in range(3):
            out |= padded[dr : dr + height, dc : dc + width]
    return out


def free_cells(grid: OccupancyMap) -> np.ndarray:
    """The known-free cells, where global localization may put a particle, as row-major flat indices (row * width +
    col): np.argwhere's (row, col) pairs in the same order take several times as long for the warehouse's 1.7
    million cells, at every simulator start."""
    return np.flatnonzero((grid.data >= 0) & (grid.data < 25))


class LikelihoodField:
    """The per-cell beam likelihood pz of a map, padded by one cell of 'off the map', for one lookup per beam."""

    def __init__(
        self,
        grid: OccupancyMap,
        z_hit: float,
        z_rand: float,
        sigma_hit: float,
        max_dist: float,
        max_beams: int,
        range_max: float,
        range_min: float,
    ) -> None:
        for name, value in (("z_hit", z_hit), ("z_rand", z_rand), ("laser_likelihood_max_dist", max_dist)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be a finite number >= 0, got {value}")
        if not (math.isfinite(sigma_hit) and sigma_hit > 0.0):
            raise ValueError(f"sigma_hit must be > 0, got {sigma_hit}")
        if max_beams < 2:
            raise ValueError(f"max_beams must be at least 2, got {max_beams}")
        self.grid = grid
        self.max_beams = int(max_beams)
        self.range_max_param = float(range_max)  # <= 0: use the scan's range_max
        self.range_min_param = float(range_min)
        self.z_hit, self.z_rand, self.sigma_hit, self.max_dist = z_hit, z_rand, sigma_hit, max_dist
        # The surfaces a lidar can see: occupied cells next to a known-free cell. A SLAM map holds little else,
        # but our worlds' maps fill walls and the outside solid; measuring the distance to every occupied cell
        # would make a beam ending anywhere inside a wall look like a perfect hit (zero distance), and the
        # filter could slide into walls at no cost. Maps with thin walls give the same field either way.
        solid = grid.data >= 65
        free = (grid.data >= 0) & (grid.data < 25)
        occupied = solid & _touching(free)
        if not occupied.any():
            occupied = solid
        res = grid.resolution
        dist = distance_to_marked(occupied, res)  # inf everywhere when nothing is occupied
        dist = np.minimum(dist, max_dist)
        self.dist = np.pad(dist, 1, mode="constant", constant_values=max_dist)
        self._rows, self._cols = self.dist.shape
        self._pz_cache: tuple[float, np.ndarray] | None = None

    def _table(self, range_max: float) -> np.ndarray:
        """pz per cell for a given range_max (z_rand's density is 1/range_max), flattened; cached."""
        if self._pz_cache is None or self._pz_cache[0] != range_max:
            d = self.dist
            pz = self.z_hit * np.exp(-(d * d) / (2.0 * self.sigma_hit**2)) + self.z_rand / range_max
            self._pz_cache = (range_max, pz.ravel())
        return self._pz_cache[1]

    def beams(
        self, ranges: np.ndarray, angle_min: float, angle_increment: float, scan_range_min: float, scan_range_max: float
    ) -> tuple[np.ndarray, np.ndarray, float]:
        """The max_beams evenly spaced beams Nav2 uses, as end points in the robot frame, and the range_max."""
        r = np.asarray(ranges, dtype=np.float64)
        n = len(r)
        range_max = self.range_max_param if self.range_max_param > 0.0 else float(scan_range_max)
        range_min = self.range_min_param if self.range_min_param > 0.0 else float(scan_range_min)
        if not (math.isfinite(range_max) and range_max > 0.0):
            raise ValueError(f"laser range_max must be a positive number, got {range_max}")
        step = max((n - 1) // (self.max_beams - 1), 1)
        idx = np.arange(0, n, step)
        rr = r[idx]
        rr = np.where(rr <= range_min, range_max, rr)  # too close reads as 'nothing seen', as in Nav2
        use = np.isfinite(rr) & (rr < range_max)
        bearing = angle_min + idx[use] * angle_increment
        rr = rr[use]
        return rr * np.cos(bearing), rr * np.sin(bearing), range_max

    def likelihoods(self, poses: np.ndarray, bx: np.ndarray, by: np.ndarray, range_max: float) -> np.ndarray:
        """1 + sum over beams of pz^3 for every particle, beams given as robot-frame end points (bx, by)."""
        table = self._table(range_max)
        if len(bx) == 0:
            return np.ones(len(poses))
        g = self.grid
        inv = 1.0 / g.resolution
        c, s = np.cos(poses[:, 2])[:, None], np.sin(poses[:, 2])[:, None]
        ex = poses[:, 0:1] + c * bx - s * by
        ey = poses[:, 1:2] + s * bx + c * by
        col = np.floor((ex - g.origin_x) * inv)
        row = np.floor((ey - g.origin_y) * inv)
        np.clip(col, -1, self._cols - 2, out=col)  # one padding cell each side: 'off the map'
        np.clip(row, -1, self._rows - 2, out=row)
        flat = (row.astype(np.intp) + 1) * self._cols + (col.astype(np.intp) + 1)
        pz = table.take(flat)
        return 1.0 + (pz * pz * pz).sum(axis=1)
