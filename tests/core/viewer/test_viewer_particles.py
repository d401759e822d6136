"""The viewer shows AMCL's particle cloud: thinned for the browser, garbage dropped."""

from __future__ import annotations

import numpy as np
import pytest

from tb4.viewer.state import PARTICLE_POINTS, ClientCursor, ViewerState

pytestmark = pytest.mark.core


def test_particle_cloud_is_thinned_and_cleaned() -> None:
    state = ViewerState()
    assert state.snapshot(ClientCursor())["particles"] == []
    rng = np.random.default_rng(0)
    cloud = rng.normal(0.0, 1.0, size=(2000, 2))
    cloud[5] = (np.nan, 1.0)
    cloud[6] = (np.inf, 0.0)
    state.set_particles(cloud)
    flat = state.snapshot(ClientCursor())["particles"]
    assert 0 < len(flat) // 2 <= PARTICLE_POINTS and len(flat) % 2 == 0
    assert np.all(np.isfinite(flat))
    state.set_particles(np.zeros((0, 2)))
    assert state.snapshot(ClientCursor())["particles"] == []
