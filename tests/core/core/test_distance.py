"""tb4.core.distance: the exact Euclidean distance transform (C kernel), against SciPy's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt

from tb4.core.distance import distance_to_marked
from tb4.sim.world import load_world

pytestmark = pytest.mark.core


@pytest.mark.parametrize(
    ("shape", "density"),
    [((1, 1), 1.0), ((1, 9), 0.3), ((9, 1), 0.3), ((57, 83), 0.01), ((200, 130), 0.2), ((300, 300), 5e-4)],
)
def test_the_same_distances_as_scipy_to_the_last_bit(shape: tuple[int, int], density: float) -> None:
    rng = np.random.default_rng(shape[0] * 1000 + shape[1])
    marked = rng.random(shape) < density
    marked.flat[rng.integers(marked.size)] = True
    assert np.array_equal(distance_to_marked(marked), distance_transform_edt(~marked))
    sized = distance_to_marked(marked, 0.05)
    np.testing.assert_allclose(sized, distance_transform_edt(~marked, sampling=0.05), rtol=1e-15, atol=0.0)


def test_shipped_maps_and_corner_cases() -> None:
    for name in ("warehouse", "depot"):
        occupied = load_world(name).map.occupied_mask()
        assert np.array_equal(distance_to_marked(occupied), distance_transform_edt(~occupied))
    only_corner = np.zeros((3, 4), dtype=bool)
    only_corner[0, 0] = True
    np.testing.assert_array_equal(distance_to_marked(only_corner, 2.0)[2], 2.0 * np.hypot(2, np.arange(4)))
    assert np.isinf(distance_to_marked(np.zeros((2, 3), dtype=bool))).all()  # nothing marked: nothing near
    assert distance_to_marked(np.zeros((0, 5), dtype=bool)).shape == (0, 5)
    with pytest.raises(ValueError, match="2D"):
        distance_to_marked(np.zeros(4, dtype=bool))
