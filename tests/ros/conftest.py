"""Fixtures for integration tests over real DDS: a real simulator process and a raw rclpy client."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")


from .rosclient import RosClient  # noqa: E402


@pytest.fixture
def ros() -> Iterator[RosClient]:
    client = RosClient()
    yield client
    client.close()
