"""The particle filter under AMCL (Nav2's pf.c semantics), vectorised with NumPy.

Samples are poses (x, y, yaw) with weights. What this module owns:
- initialisation from a Gaussian (an initial pose) or uniformly over free space (global localization);
- the sensor step's bookkeeping: normalisation and the slow/fast weight averages behind recovery
  (recovery_alpha_slow / recovery_alpha_fast), with a reset to uniform weights when every weight is zero;
- KLD-adaptive resampling: draw from the weights, or a random free-space pose with probability
  max(0, 1 - w_fast / w_slow), until the sample count exceeds the KLD bound for the histogram bins occupied
  so far (bins of 0.5 m x 0.5 m x 10 deg, bounds min/max_particles, pf_err, pf_z);
- clustering (connected occupied bins) and the pose estimate: the mean and covariance of the heaviest cluster.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from tb4.core.geometry import wrap_angle

__all__ = ["ParticleFilter", "PoseEstimate", "kld_limit", "BIN_SIZE"]

BIN_SIZE = (0.5, 0.5, math.radians(10.0))  # the kd-tree cell of pf.c
_FIRST_PREFIX = 1024  # samples binned first when resampling (grown x4 until the KLD bound is passed)

FreePoseSampler = Callable[[int, np.random.Generator], np.ndarray]


def kld_limit(k: np.ndarray | int, pf_err: float, pf_z: float, min_samples: int, max_samples: int) -> np.ndarray:
    """Samples needed so the KL divergence to the true posterior stays below pf_err with quantile pf_z,
    for k occupied bins (pf_resample_limit, Fox 2003), clamped to [min_samples, max_samples]."""
    k = np.asarray(k, dtype=np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    b = 2.0 / (9.0 * km1)
    x = 1.0 - b + np.sqrt(b) * pf_z
    n = np.ceil(km1 / (2.0 * pf_err) * x * x * x)
    n = np.where(k <= 1.0, float(max_samples), n)
    return np.clip(n, min_samples, max_samples)


def _bin_keys(poses: np.ndarray) -> np.ndarray:
    """One int64 per sample naming its histogram bin."""
    ix = np.floor(poses[:, 0] / BIN_SIZE[0]).astype(np.int64)
    iy = np.floor(poses[:, 1] / BIN_SIZE[1]).astype(np.int64)
    ia = np.floor(poses[:, 2] / BIN_SIZE[2]).astype(np.int64)
    return ((ix + (1 << 20)) << 42) | ((iy + (1 << 20)) << 21) | (ia + 64)


@dataclass(frozen=True)
class PoseEstimate:
    """Mean pose and 3x3 covariance (x, y, yaw) of the heaviest cluster, its weight share and the cluster count."""

    pose: tuple[float, float, float]
    cov: np.ndarray
    weight: float
    clusters: int


class ParticleFilter:
    """Samples, weights and the adaptive resampling of Nav2's pf.c; the models live elsewhere."""

    def __init__(
        self,
        min_particles: int,
        max_particles: int,
        pf_err: float,
        pf_z: float,
        alpha_slow: float,
        alpha_fast: float,
        free_pose_sampler: FreePoseSampler,
        rng: np.random.Generator,
    ) -> None:
        if not (1 <= min_particles <= max_particles):
            raise ValueError(f"need 1 <= min_particles <= max_particles, got {min_particles}, {max_particles}")
        if not (0.0 < pf_err < 1.0):
            raise ValueError(f"pf_err must be within (0, 1), got {pf_err}")
        for name, a in (("recovery_alpha_slow", alpha_slow), ("recovery_alpha_fast", alpha_fast)):
            if not (0.0 <= a <= 1.0):
                raise ValueError(f"{name} must be within [0, 1], got {a}")
        self.min_particles = int(min_particles)
        self.max_particles = int(max_particles)
        self.pf_err = float(pf_err)
        self.pf_z = float(pf_z)
        self.alpha_slow = float(alpha_slow)
        self.alpha_fast = float(alpha_fast)
        self.sample_free = free_pose_sampler
        self.rng = rng
        self.poses = np.zeros((0, 3))
        self.weights = np.zeros(0)
        self.w_slow = 0.0
        self.w_fast = 0.0
        self.converged = False

    @property
    def count(self) -> int:
        return len(self.weights)

    # --- initialisation ---------------------------------------------------------------------------------
    def init_gaussian(self, mean: tuple[float, float, float], cov: np.ndarray) -> None:
        """max_particles samples around `mean` (pf_init): the filter starts wide and KLD shrinks it."""
        cov = np.asarray(cov, dtype=np.float64).reshape(3, 3)
        cov = 0.5 * (cov + cov.T)
        vals, vecs = np.linalg.eigh(cov)
        std = np.sqrt(np.clip(vals, 0.0, None))
        draws = self.rng.standard_normal((self.max_particles, 3)) * std
        poses = draws @ vecs.T + np.asarray(mean, dtype=np.float64)
        poses[:, 2] = wrap_angle(poses[:, 2])
        self._reset(poses)

    def init_uniform(self) -> None:
        """max_particles samples uniformly over free space (global localization)."""
        self._reset(self.sample_free(self.max_particles, self.rng))

    def _reset(self, poses: np.ndarray) -> None:
        self.poses = np.ascontiguousarray(poses, dtype=np.float64)
        self.weights = np.full(len(poses), 1.0 / len(poses))
        self.w_slow = self.w_fast = 0.0
        self.converged = False

    # --- sensor step --------------------------------------------------------------------------------------
    def apply_likelihoods(self, likelihood: np.ndarray) -> None:
        """Multiply the weights by the sensor model's likelihoods, normalise, update w_slow / w_fast."""
        w = self.weights * np.asarray(likelihood, dtype=np.float64)
        total = float(w.sum())
        if total > 0.0 and math.isfinite(total):
            self.weights = w / total
            w_avg = total / len(w)
            self.w_slow = w_avg if self.w_slow == 0.0 else self.w_slow + self.alpha_slow * (w_avg - self.w_slow)
            self.w_fast = w_avg if self.w_fast == 0.0 else self.w_fast + self.alpha_fast * (w_avg - self.w_fast)
        else:  # every sample impossible: start over from equal weights rather than divide by zero
            self.weights = np.full(len(w), 1.0 / len(w))

    # --- resampling ---------------------------------------------------------------------------------------
    def resample(self) -> None:
        """KLD-adaptive resampling with random-pose injection when w_fast falls below w_slow.

        pf.c stops drawing once the count passes the KLD bound of the bins seen so far, which needs only the first
        samples. The random numbers for all max_particles draws are taken as before (the stream, and so every seeded
        run, is unchanged), but only a prefix is binned, growing until the bound is passed: once converged that is
        about min_particles of max_particles samples."""
        w_diff = 1.0 - self.w_fast / self.w_slow if self.w_slow > 0.0 else 0.0
        w_diff = max(w_diff, 0.0)
        m = self.max_particles
        cdf = np.cumsum(self.weights)
        cdf /= cdf[-1]
        draws = self.rng.random(m)
        inject = injected = None
        if w_diff > 0.0:
            inject = self.rng.random(m) < w_diff
            n_inject = int(inject.sum())
            injected = self.sample_free(n_inject, self.rng) if n_inject else None
        floor = min(self.min_particles, m)
        length = min(m, max(_FIRST_PREFIX, 2 * floor))
        while True:
            poses = self._draw(cdf, draws[:length], inject, injected)
            count = self._kld_count(poses)
            if count is not None or length == m:
                break
            length = min(m, 4 * length)
        count = max(count if count is not None else m, floor)
        self.poses = poses[:count].copy()
        self.weights = np.full(count, 1.0 / count)
        if w_diff > 0.0:
            self.w_slow = self.w_fast = 0.0

    def _draw(
        self, cdf: np.ndarray, draws: np.ndarray, inject: np.ndarray | None, injected: np.ndarray | None
    ) -> np.ndarray:
        """The first len(draws) samples: picked by weight, or the next free-space poses where `inject` says."""
        picks = np.minimum(np.searchsorted(cdf, draws, side="right"), len(cdf) - 1)
        poses = self.poses[picks]
        if injected is not None and inject is not None:
            here = inject[: len(draws)]
            poses[here] = injected[: int(here.sum())]
        return poses

    def _kld_count(self, poses: np.ndarray) -> int | None:
        """The first sample count above the KLD bound of the bins occupied so far; None if none in `poses`."""
        _, first = np.unique(_bin_keys(poses), return_index=True)
        first.sort()
        n = np.arange(1, len(poses) + 1)
        k = np.searchsorted(first, n - 1, side="right")
        over = n > kld_limit(k, self.pf_err, self.pf_z, self.min_particles, self.max_particles)
        return int(np.argmax(over)) + 1 if over.any() else None

    # --- estimate -----------------------------------------------------------------------------------------
    def estimate(self) -> PoseEstimate:
        """Mean and covariance of the heaviest cluster of connected histogram bins (pf_cluster_stats)."""
        poses, w = self.poses, self.weights
        labels, n_clusters = _cluster(poses)
        sums = np.bincount(labels, weights=w, minlength=n_clusters)
        best = int(np.argmax(sums))
        sel = labels == best
        ws = w[sel]
        total = float(ws.sum())
        if total <= 0.0:
            ws = np.full(len(ws), 1.0 / max(len(ws), 1))
            total = 1.0
        p = poses[sel]
        mx = float(np.dot(ws, p[:, 0]) / total)
        my = float(np.dot(ws, p[:, 1]) / total)
        c = float(np.dot(ws, np.cos(p[:, 2])) / total)
        s = float(np.dot(ws, np.sin(p[:, 2])) / total)
        yaw = math.atan2(s, c)
        dx, dy = p[:, 0] - mx, p[:, 1] - my
        cov = np.zeros((3, 3))
        cov[0, 0] = np.dot(ws, dx * dx) / total
        cov[0, 1] = cov[1, 0] = np.dot(ws, dx * dy) / total
        cov[1, 1] = np.dot(ws, dy * dy) / total
        cov[2, 2] = -2.0 * math.log(max(math.hypot(c, s), 1e-12))
        return PoseEstimate((mx, my, yaw), cov, total / float(w.sum()), n_clusters)


#: the 13 neighbour offsets (dx, dy, da) of a bin that come after it in raster order; with their mirror images
#: they are its 26 neighbours across faces, edges and corners
_FORWARD_NEIGHBOURS = np.array(
    [(dx, dy, da) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for da in (-1, 0, 1) if (dx, dy, da) > (0, 0, 0)],
    dtype=np.int64,
)


def _cluster(poses: np.ndarray) -> tuple[np.ndarray, int]:
    """Label each sample with its cluster: occupied bins joined across faces, edges and corners, heading wrapping.

    Clusters are numbered in the raster order (x, then y, then heading bin) of their first bin. Only the occupied
    bins are looked at (a few hundred), not a grid over the samples' extent, so a filter spread over a whole map
    costs no more memory than one around the robot.
    """
    ix = np.floor(poses[:, 0] / BIN_SIZE[0]).astype(np.int64)
    iy = np.floor(poses[:, 1] / BIN_SIZE[1]).astype(np.int64)
    na = int(round(2.0 * math.pi / BIN_SIZE[2]))
    ia = np.floor((poses[:, 2] + math.pi) / BIN_SIZE[2]).astype(np.int64) % na
    ix -= ix.min()
    iy -= iy.min()
    ny = int(iy.max()) + 2  # a spare row, so that y + 1 never aliases the next x
    bins, sample_bin = np.unique((ix * ny + iy) * na + ia, return_inverse=True)
    bx, by, ba = bins // (ny * na), (bins // na) % ny, bins % na
    # pairs of occupied neighbouring bins, all 13 forward offsets at once (the heading wraps: bins at -180 and
    # +180 deg touch)
    dx, dy, da = (_FORWARD_NEIGHBOURS[:, k : k + 1] for k in range(3))
    y = by + dy
    key = ((bx + dx) * ny + y) * na + (ba + da) % na
    at = np.minimum(np.searchsorted(bins, key), len(bins) - 1)
    offset, a = np.nonzero((bins[at] == key) & (y >= 0))
    b = at[offset, a]
    # each bin takes the smallest bin index it is connected to: hook to the smallest neighbour, then jump pointers
    root = np.arange(len(bins))
    while True:
        hooked = root.copy()
        np.minimum.at(hooked, a, root[b])
        np.minimum.at(hooked, b, root[a])
        hooked = hooked[hooked]
        if np.array_equal(hooked, root):
            break
        root = hooked
    _, cluster_of_bin = np.unique(root, return_inverse=True)
    labels = cluster_of_bin.reshape(-1)[sample_bin.reshape(-1)]
    return labels.astype(np.int64), int(labels.max()) + 1
