"""Fixtures for integration tests over real DDS: a real simulator process and a raw rclpy client."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")


from .rosclient import RosClient  # noqa: E402


@pytest.fixture
def ros() -> Iterator[RosClient]:
    client = RosClient()
    yield client
    client.close()


@pytest.fixture
def navigators() -> Iterator[list[Any]]:
    """rclpy initialised; navigators appended to the list are destroyed at teardown, then rclpy shut down."""
    import rclpy

    if not rclpy.ok():
        rclpy.init()
    made: list[Any] = []
    yield made
    for nav in made:
        nav.destroyNode()
    rclpy.try_shutdown()
