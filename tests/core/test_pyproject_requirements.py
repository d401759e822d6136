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
