"""Fixtures for the language tests: the depot world and a recording test target for the executor (no ROS)."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from language_test_targets import RecordingNavigator

from tb4.language.world_context import destination_table, pose_checker
from tb4.sim.world import World, load_world


@pytest.fixture(scope="session")
def depot() -> World:
    return load_world("depot")


@pytest.fixture(scope="session")
def depot_context(depot: World) -> tuple[dict[str, list[float]], Callable[[float, float], str | None]]:
    return destination_table(depot), pose_checker(depot)


@pytest.fixture
def recorder() -> RecordingNavigator:
    return RecordingNavigator()
