"""The overlay environment's inputs (tools/install.sh's TB4_BASE_VENV, CMake's TB4_INTERFACE_PACKAGES, the base path
in tools/venv_overlay.py's hook) refuse what they cannot use with a message, before changing anything.

That an overlay built from them works (its nav2_msgs first on every search path) is checked in the Jazzy stage of
make test, which runs in one: tests/core/test_wire.py and the DDS suites.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _install(tmp_path: Path, base: str, venv: Path) -> subprocess.CompletedProcess:
    env = {**os.environ, "TB4_BASE_VENV": base, "VENV": str(venv), "TB4_ROS_DISTRO": "jazzy"}
    return subprocess.run(
        ["bash", str(ROOT / "tools" / "install.sh")], env=env, capture_output=True, text=True, timeout=60, cwd=tmp_path
    )


def test_install_refuses_a_base_that_is_not_an_installed_environment(tmp_path: Path) -> None:
    venv = tmp_path / "overlay"
    for base in (str(tmp_path / "missing"), str(tmp_path), "/"):
        done = _install(tmp_path, base, venv)
        assert done.returncode != 0, base
        assert "no installed environment there (make install first)" in done.stderr, (base, done.stderr)
        assert not venv.exists(), base


def test_install_refuses_an_environment_overlaying_itself(tmp_path: Path) -> None:
    done = _install(tmp_path, sys.prefix, Path(sys.prefix))  # this test's own, installed environment
    assert done.returncode != 0
    assert "an environment cannot overlay itself" in done.stderr, done.stderr


def test_cmake_refuses_an_unknown_interface_package(tmp_path: Path) -> None:
    cmake = shutil.which("cmake", path=str(Path(sys.prefix) / "bin")) or shutil.which("cmake")
    assert cmake, "cmake is installed with the project's build tools"
    done = subprocess.run(
        [cmake, "-S", str(ROOT), "-B", str(tmp_path / "build"), f"-DPython3_EXECUTABLE={sys.executable}",
         "-DTB4_INTERFACE_PACKAGES=nav2_msgs;nav2_msg"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode != 0
    assert "TB4_INTERFACE_PACKAGES names 'nav2_msg'" in " ".join(done.stderr.split()), done.stderr


def test_a_hook_whose_base_is_gone_says_so_and_the_interpreter_goes_on() -> None:
    code = (
        f"import sys; sys.path.insert(0, {str(ROOT / 'tools')!r}); import venv_overlay; "
        "venv_overlay.activate('/nonexistent/base'); print('still running')"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "still running"  # no re-exec, no traceback
    assert "overlays /nonexistent/base, which has no" in done.stderr and "make install-jazzy-wire" in done.stderr


def test_search_paths_put_the_overlay_first_once() -> None:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import venv_overlay
    finally:
        sys.path.pop(0)
    joined = venv_overlay._first(["/o/lib", "/b/lib"], os.pathsep.join(["/b/lib", "", "/x", "/o/lib", "/x"]))
    assert joined.split(os.pathsep) == ["/o/lib", "/b/lib", "/x"]
