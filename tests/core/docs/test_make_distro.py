"""`make` builds .venv for Kilted and .venv-jazzy for Jazzy, whatever TB4_ROS_DISTRO says: a Jazzy wish for the
Kilted environment (`TB4_ROS_DISTRO=jazzy make install`, the variable tools/install.sh reads) stops before anything
runs and names `make install-jazzy`, instead of building Kilted without a word. Checked with `make --dry-run`.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[3]


def _make(*args: str, distro: str | None) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith(("MAKE", "MFLAGS"))}
    env.pop("TB4_ROS_DISTRO", None)
    if distro is not None:
        env["TB4_ROS_DISTRO"] = distro
    return subprocess.run(
        ["make", "--dry-run", "--no-print-directory", *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_a_jazzy_wish_for_the_kilted_environment_stops_and_names_the_jazzy_target() -> None:
    for target in ("install", "test", "demo"):
        refused = _make(target, distro="jazzy")
        assert refused.returncode != 0 and "make install-jazzy" in refused.stderr, refused.stderr
        assert refused.stdout == ""  # nothing would have run
    assert _make("install", distro="kilted").returncode == 0
    assert _make("install", distro=None).returncode == 0
    for target in ("install-jazzy", "install-jazzy-wire", "test-cross-distro"):  # the Jazzy targets agree with it
        assert _make(target, distro="jazzy").returncode == 0, target
