"""Named places found through a running simulator's `world` topic, as a user's script finds them."""

from __future__ import annotations

import time

import pytest

from tb4.places import Places, PlacesUnavailable


def test_a_script_finds_the_simulators_places_by_its_world_topic(start_simulator) -> None:
    start_simulator("--world", "depot", "--namespace", "robot2")
    places = Places.of_robot(namespace="/robot2", timeout=20.0)
    assert places.source == "world depot" and "wood crate" in places


def test_no_world_announced_is_a_clear_error_in_bounded_time() -> None:
    started = time.monotonic()
    with pytest.raises(PlacesUnavailable, match="no world announced on '/nobody/world' within 1 s"):
        Places.of_robot(namespace="/nobody", timeout=1.0)
    assert time.monotonic() - started < 10
