"""The test harness itself: what `make test` relies on from pytest and pytest-xdist."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.core

GROUPED = """
import pytest

pytestmark = pytest.mark.xdist_group("shared")

@pytest.mark.parametrize("i", range(6))
def test_grouped(i):
    pass
"""


def test_loadgroup_keeps_a_group_on_one_worker(tmp_path: Path) -> None:
    """make test runs `-n 2 --dist loadgroup`: the tests of an xdist_group (they share a module-scoped simulator)
    must run on one worker. With pytest 9.2 and pytest-xdist 3.8 they did not (each worker started its own)."""
    (tmp_path / "test_grouped.py").write_text(GROUPED)
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "2", "--dist", "loadgroup", "-v"],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    workers = {line.split()[0] for line in run.stdout.splitlines() if "PASSED test_grouped.py" in line}
    assert len(workers) == 1, f"the group ran on {sorted(workers)}:\n{run.stdout}"
    assert "test_grouped[0]@shared" in run.stdout  # the group's suffix: how pytest-xdist schedules a group
