"""AMCL's clustering of samples (pf_cluster_stats): the same partition and numbering as labelling a dense 3D grid
of histogram bins with scipy.ndimage (26-connected, heading wrapping), which it replaced."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from tb4.nav.particle_filter import BIN_SIZE, _cluster

pytestmark = pytest.mark.core


def _cluster_on_a_dense_grid(poses: np.ndarray) -> np.ndarray:
    """The reference (the previous implementation): label a boolean grid over the samples' extent with
    scipy.ndimage, then join labels that meet across the first and last heading layers."""
    ix = np.floor(poses[:, 0] / BIN_SIZE[0]).astype(np.int64)
    iy = np.floor(poses[:, 1] / BIN_SIZE[1]).astype(np.int64)
    na = int(round(2.0 * math.pi / BIN_SIZE[2]))
    ia = np.floor((poses[:, 2] + math.pi) / BIN_SIZE[2]).astype(np.int64) % na
    ix -= ix.min()
    iy -= iy.min()
    shape = (int(ix.max()) + 1, int(iy.max()) + 1, na)
    grid = np.zeros(shape, dtype=bool)
    grid[ix, iy, ia] = True
    lab, n = ndimage.label(grid, structure=np.ones((3, 3, 3), dtype=bool))
    first, last = lab[:, :, 0], lab[:, :, -1]
    parent = list(range(n + 1))

    def find(a: int) -> int:
        while parent[a] != a:
            a = parent[a]
        return a

    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            a = first[max(dx, 0) : shape[0] + min(dx, 0), max(dy, 0) : shape[1] + min(dy, 0)]
            b = last[max(-dx, 0) : shape[0] + min(-dx, 0), max(-dy, 0) : shape[1] + min(-dy, 0)]
            both = (a > 0) & (b > 0)
            for u, v in zip(a[both].tolist(), b[both].tolist(), strict=True):
                ru, rv = find(u), find(v)
                parent[max(ru, rv)] = min(ru, rv)
    roots = np.array([find(i) for i in range(n + 1)])
    compact = np.unique(roots, return_inverse=True)[1].reshape(-1)
    return compact[lab[ix, iy, ia]] - 1


def _scatter(rng: np.random.Generator, centres: list[tuple[float, float, float]], n: int, spread: float) -> np.ndarray:
    parts = []
    for cx, cy, ca in centres:
        p = np.column_stack([rng.normal(cx, spread, n), rng.normal(cy, spread, n), rng.normal(ca, 0.3, n)])
        p[:, 2] = (p[:, 2] + math.pi) % (2 * math.pi) - math.pi
        parts.append(p)
    return np.concatenate(parts)


@pytest.mark.parametrize("seed", range(12))
def test_clusters_match_a_dense_grid_labelling(seed: int) -> None:
    rng = np.random.default_rng(seed)
    count = 1 + seed % 4
    centres = [(rng.uniform(-20, 20), rng.uniform(-20, 20), rng.uniform(-math.pi, math.pi)) for _ in range(count)]
    poses = _scatter(rng, centres, 500, spread=[0.2, 0.6, 1.5][seed % 3])
    labels, n = _cluster(poses)
    reference = _cluster_on_a_dense_grid(poses)
    assert n == int(reference.max()) + 1
    assert np.array_equal(labels, reference)


def test_headings_at_minus_and_plus_180_degrees_are_one_cluster() -> None:
    poses = np.array([[1.0, 1.0, -math.pi + 0.01], [1.0, 1.0, math.pi - 0.01], [5.0, 5.0, 0.0]])
    labels, n = _cluster(poses)
    assert n == 2 and labels[0] == labels[1] != labels[2]
    assert np.array_equal(labels, _cluster_on_a_dense_grid(poses))


def test_bins_touching_only_at_a_corner_are_joined_and_a_gap_of_one_bin_separates() -> None:
    corner = np.array([[0.1, 0.1, 0.0], [0.6, 0.6, BIN_SIZE[2]]])  # next bin in x, y and heading
    assert _cluster(corner)[1] == 1
    gap = np.array([[0.1, 0.1, 0.0], [1.1, 0.1, 0.0]])  # one empty bin between them in x
    labels, n = _cluster(gap)
    assert n == 2 and list(labels) == [0, 1]


def test_samples_spread_over_a_whole_map_are_clustered_without_a_dense_grid() -> None:
    rng = np.random.default_rng(7)
    poses = np.column_stack(
        [rng.uniform(0, 5000, 2000), rng.uniform(0, 5000, 2000), rng.uniform(-math.pi, math.pi, 2000)]
    )  # a dense grid would have 10,000 x 10,000 x 36 bins
    labels, n = _cluster(poses)
    assert labels.shape == (2000,) and n == len(np.unique(labels))
    assert n > 1900  # samples 110 m apart on average: almost every one is a cluster of its own
