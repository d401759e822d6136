"""Fixtures for integration tests over real DDS: a real simulator process and a raw rclpy client."""

from __future__ import annotations

import sys
from collections.abc import Callable, Iterator

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")

from tb4.processes import ManagedProcess  # noqa: E402

from .rosclient import RosClient  # noqa: E402


@pytest.fixture
def start_simulator(start_process) -> Callable[..., ManagedProcess]:
    """Start `tb4 sim` with the given options and wait until it is serving.

    With `--rate max`, add `--hold` where the test's first act is a command (an action goal, a Create 3 service):
    until then the simulator runs at real time instead of burning a core on the dock while the test's clients
    start and discover it, CPU the tests running beside it need (make test runs several at once)."""

    def _start(*options: str, name: str = "sim") -> ManagedProcess:
        proc = start_process([sys.executable, "-m", "tb4.cli.main", "sim", *options], name=name)
        if not proc.wait_for_output("tb4 sim ready", timeout=60):
            raise AssertionError(f"simulator did not start:\n{proc.output()}")
        return proc

    return _start


@pytest.fixture
def ros() -> Iterator[RosClient]:
    client = RosClient()
    yield client
    client.close()
