"""tools/pyproject_requirements.py, the one reader of pyproject.toml's requirement lists (tools/install.sh installs
them; the interface cache keys its build on the build's): the lists as install.sh needs them, and a file without
them refused by name."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

from pyproject_requirements import requirements  # noqa: E402


def test_the_build_list_comes_first_and_every_requirement_once() -> None:
    build = requirements(ROOT / "pyproject.toml", "build")
    every = requirements(ROOT / "pyproject.toml", "all")
    assert build and every[: len(build)] == build and len(every) > len(build)
    assert len(every) == len(set(every))
    assert not any(r.startswith("turtlebot4-navigator") for r in every)  # the [all] extra's self-reference


def test_a_pyproject_without_the_lists_is_refused_by_name(tmp_path: Path) -> None:
    broken = tmp_path / "pyproject.toml"
    broken.write_text('[build-system]\nrequires = ["numpy"]\n[project]\nname = "x"\n')
    assert requirements(broken, "build") == ["numpy"]
    with pytest.raises(ValueError, match=r"pyproject.toml: no \[project\] dependencies list"):
        requirements(broken, "all")
    with pytest.raises(ValueError, match="which must be"):
        requirements(broken, "everything")
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "pyproject_requirements.py"), "all", str(broken)],
        capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert done.returncode != 0 and "no [project] dependencies list" in done.stderr


def test_jazzys_lists_replace_every_ros_wheel_and_keep_the_rest() -> None:
    for which in ("build", "all"):
        kilted = requirements(ROOT / "pyproject.toml", which)
        jazzy = requirements(ROOT / "pyproject.toml", which, "jazzy")
        assert [r for r in jazzy if not r.startswith("ros-")] == [r for r in kilted if not r.startswith("ros-")]
        ros = [r for r in jazzy if r.startswith("ros-")]
        # every ROS wheel pinned through its Jazzy meta package, which pins the ros-* wheels of that release
        assert ros and all(r.startswith("ros-jazzy-") and "==" in r for r in ros), ros
    runtime = requirements(ROOT / "pyproject.toml", "all", "jazzy")
    assert "ros-jazzy-rclpy==7.1.6" in runtime and "ros-jazzy-rmw-fastrtps-cpp==8.4.3" in runtime
    with pytest.raises(ValueError, match="distro must be"):
        requirements(ROOT / "pyproject.toml", "build", "humble")
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "pyproject_requirements.py"), "build", "--distro", "jazzy"],
        capture_output=True, text=True, timeout=30, cwd=ROOT,
    )  # fmt: skip
    assert done.returncode == 0 and done.stdout.split("\n")[0].startswith("ros-jazzy-"), done.stdout
