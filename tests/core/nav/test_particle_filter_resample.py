"""KLD resampling bins only the prefix of the draws it needs: the same samples, count and random stream as
binning all max_particles draws (tests/core/nav/resample_reference.py), whatever the weights and injection."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from resample_reference import resample_reference  # tests/core/nav on sys.path

from tb4.nav.particle_filter import ParticleFilter

pytestmark = pytest.mark.core


def free_poses(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.column_stack([rng.uniform(-20, 20, n), rng.uniform(-15, 15, n), rng.uniform(-np.pi, np.pi, n)])


def a_filter(case: int) -> ParticleFilter:
    rng = np.random.default_rng(case)
    low = int(rng.choice([1, 50, 500, 2000]))
    high = int(rng.choice([low, low + 1, 2000, 5000, 10_000]))
    pf = ParticleFilter(low, max(low, high), 0.05, 0.99, 0.001, 0.1, free_poses, np.random.default_rng(100 + case))
    spread = float(rng.choice([0.05, 0.5, 5.0, 30.0]))  # converged ... lost
    pf.init_gaussian((1.0, -2.0, 0.3), np.diag([spread, spread, min(spread, 3.0)]))
    if rng.random() < 0.3:
        pf.init_uniform()
    weights = rng.random(pf.count) ** float(rng.choice([1, 8, 50]))  # flat ... one dominant sample
    if rng.random() < 0.2:
        weights[rng.random(pf.count) < 0.9] = 0.0
    weights[0] += 1e-12
    pf.weights = weights / weights.sum()
    pf.w_slow, pf.w_fast = [(0.0, 0.0), (1e-3, 1e-3), (1e-3, 5e-4), (1e-3, 1e-6), (2e-3, 0.0)][case % 5]
    return pf


@pytest.mark.parametrize("case", range(60))
def test_resample_matches_binning_every_draw(case: int) -> None:
    ours, reference = a_filter(case), a_filter(case)
    for _ in range(3):  # the second and third rounds start from a KLD-sized set
        resample_reference(reference)
        ours.resample()
        assert ours.count == reference.count
        assert np.array_equal(ours.poses, reference.poses)
        assert np.array_equal(ours.weights, reference.weights)
        assert (ours.w_slow, ours.w_fast) == (reference.w_slow, reference.w_fast)
        assert ours.rng.bit_generator.state == reference.rng.bit_generator.state
        state = copy.deepcopy(ours.rng.bit_generator.state)
        reference.rng.bit_generator.state = state
