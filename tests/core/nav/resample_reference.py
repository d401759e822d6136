"""The particle filter's resampling before the prefix version: it drew and binned all max_particles samples, then
kept the KLD count. Kept as the reference the C-free, cheaper version must match sample for sample."""

from __future__ import annotations

import numpy as np

from tb4.nav.particle_filter import ParticleFilter, _bin_keys, kld_limit


def resample_reference(pf: ParticleFilter) -> None:
    w_diff = 1.0 - pf.w_fast / pf.w_slow if pf.w_slow > 0.0 else 0.0
    w_diff = max(w_diff, 0.0)
    m = pf.max_particles
    cdf = np.cumsum(pf.weights)
    cdf /= cdf[-1]
    picks = np.searchsorted(cdf, pf.rng.random(m), side="right")
    picks = np.minimum(picks, len(cdf) - 1)
    poses = pf.poses[picks]
    if w_diff > 0.0:
        inject = pf.rng.random(m) < w_diff
        n_inject = int(inject.sum())
        if n_inject:
            poses[inject] = pf.sample_free(n_inject, pf.rng)
    _, first = np.unique(_bin_keys(poses), return_index=True)
    first.sort()
    n = np.arange(1, m + 1)
    k = np.searchsorted(first, n - 1, side="right")
    over = n > kld_limit(k, pf.pf_err, pf.pf_z, pf.min_particles, pf.max_particles)
    count = int(np.argmax(over)) + 1 if over.any() else m
    count = max(count, min(pf.min_particles, m))
    pf.poses = poses[:count].copy()
    pf.weights = np.full(count, 1.0 / count)
    if w_diff > 0.0:
        pf.w_slow = pf.w_fast = 0.0
