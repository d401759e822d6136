"""The interface build cache (tools/interface_cache.py): its key changes with every input of a build and only then,
an entry is stored whole or not at all, a restore names the new build's folders, and a bad cache never fails an
install. The last test drives it the way the install does: CMake's configure restores a cached entry."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tool_modules import load_tool

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[2]
cache = load_tool("interface_cache")
shared_cache = load_tool("shared_cache")


def _source(tmp_path: Path) -> Path:
    """A source tree with what the key reads: interfaces/, CMakeLists.txt and pyproject.toml."""
    src = tmp_path / "src"
    (src / "interfaces" / "nav2_msgs" / "msg").mkdir(parents=True)
    (src / "interfaces" / "nav2_msgs" / "msg" / "Costmap.msg").write_text("float32[] data\n")
    (src / "CMakeLists.txt").write_text("project(x)\n")
    (src / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["numpy>=1.24", "not-installed-anywhere"]\n'
        '[tool.tb4.jazzy]\nbuild-requires = ["not-installed-either"]\n'  # what a Jazzy build installs instead
    )
    return src


def _key(
    src: Path, distro: str = "kilted", packages: tuple[str, ...] = ("nav2_msgs",), compilers: str = "GNU 12"
) -> str:
    return shared_cache.cache_key(cache.key_inputs(src, distro, list(packages), compilers))


def test_the_key_changes_with_every_input_and_only_then(tmp_path: Path) -> None:
    src = _source(tmp_path)
    first = _key(src)
    assert _key(src) == first
    assert _key(src, packages=("nav2_msgs",)) == _key(src, packages=("nav2_msgs",))
    assert _key(src, packages=("a", "b")) == _key(src, packages=("b", "a"))  # a set, not an order
    (src / "interfaces" / "README.md").write_text("# documentation, not an input\n")
    assert _key(src) == first
    variants = {
        _key(src, distro="jazzy"),
        _key(src, packages=("nav2_msgs", "tf2_msgs")),
        _key(src, compilers="GNU 13"),
    }
    (src / "interfaces" / "nav2_msgs" / "msg" / "Costmap.msg").write_text("float64[] data\n")  # a definition
    variants.add(_key(src))
    (src / "CMakeLists.txt").write_text("project(y)\n")  # the recipe
    variants.add(_key(src))
    assert first not in variants and len(variants) == 5


def test_the_build_distributions_are_the_requirements_closure_with_versions() -> None:
    found = cache.build_distributions(["scikit-build-core", "not-installed-anywhere"])
    names = {entry.split("==")[0] for entry in found}
    assert "scikit-build-core" in names and "packaging" in names  # a requirement of a requirement
    assert all("==" in entry for entry in found) and found == sorted(found)
    assert "not-installed-anywhere" not in names
    # scikit-build-core needs typing-extensions only before Python 3.11: installed or not, no input there
    assert (sys.version_info >= (3, 11)) == ("typing-extensions" not in names)


def test_a_requirement_for_another_python_or_an_extra_pulls_nothing_in() -> None:
    assert cache._needed("typing-extensions>=4; python_version < '3.0'") is None
    assert cache._needed('typing_extensions>=4; python_version >= "3.0"') == "typing-extensions"
    assert cache._needed('pytest; extra == "test"') is None
    assert cache._needed("Ros_Rclpy==9.1") == "ros-rclpy"


def _staging(tmp_path: Path, name: str, prefix: str) -> Path:
    staging = tmp_path / name / "interfaces-install"
    (staging / "share" / "pkg" / "cmake").mkdir(parents=True)
    (staging / "share" / "pkg" / "cmake" / "export.cmake").write_text(f'INCLUDE "{prefix}/lib/numpy;{staging}"\n')
    (staging / "lib").mkdir()
    (staging / "lib" / "libpkg.so").write_bytes(b"\x7fELF\0" + str(staging).encode())  # binary: left as it is
    pycache = staging / "lib" / "pkg" / "__pycache__"
    pycache.mkdir(parents=True)
    (staging / "lib" / "pkg" / "mod.py").write_text("X = 1\n")
    (pycache / "mod.cpython-311.pyc").write_bytes(b"pyc")
    os.utime(staging / "lib" / "pkg" / "mod.py", (1_000_000, 1_000_000))
    return staging


def test_a_stored_entry_restores_into_another_clone_naming_its_folders(tmp_path: Path) -> None:
    old = _staging(tmp_path, "clone1", "/clone1/.venv")
    entry = tmp_path / "cache" / "k1"
    assert cache.store(old, entry, "/clone1/.venv", {"distro": "kilted"})
    assert json.loads((entry / cache.META).read_text())["inputs"] == {"distro": "kilted"}
    new = tmp_path / "clone2" / "interfaces-install"
    new.mkdir(parents=True)
    (new / "stale-file").write_text("from an older build")
    assert cache.restore(entry, new, "/clone2/.venv")
    text = (new / "share" / "pkg" / "cmake" / "export.cmake").read_text()
    assert text == f'INCLUDE "/clone2/.venv/lib/numpy;{new}"\n'
    assert (new / "lib" / "libpkg.so").read_bytes() == b"\x7fELF\0" + str(old).encode()
    assert (new / "lib" / "pkg" / "mod.py").stat().st_mtime == 1_000_000  # the pyc beside it stays valid
    assert not (new / "stale-file").exists() and not (new / cache.META).exists()


def test_an_incomplete_or_missing_entry_is_no_hit_and_leaves_the_staging_alone(tmp_path: Path) -> None:
    staging = _staging(tmp_path, "clone", "/p")
    before = sorted(p.relative_to(staging) for p in staging.rglob("*"))
    partial = tmp_path / "cache" / "k2"
    (partial / "share").mkdir(parents=True)  # a store that died before its marker
    for entry in (partial, tmp_path / "cache" / "missing"):
        assert not cache.restore(entry, staging, "/p")
        assert sorted(p.relative_to(staging) for p in staging.rglob("*")) == before


def test_a_cache_that_cannot_be_written_never_fails_the_build(tmp_path: Path) -> None:
    staging = _staging(tmp_path, "clone", "/p")
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the cache folder should be")
    assert not cache.store(staging, blocker / "k3", "/p")
    record = tmp_path / "inputs.json"
    record.write_text("{}")
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "interface_cache.py"), "store", str(staging), str(blocker / "k3"),
         "--prefix", "/p", "--record", str(record)],
        capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert done.returncode == 0 and "could not store the build" in done.stderr


def test_the_cache_keeps_its_most_recently_used_entries(tmp_path: Path) -> None:
    staging = _staging(tmp_path, "clone", "/p")
    folder = tmp_path / "cache"
    for k in range(cache.KEEP):
        assert cache.store(staging, folder / f"e{k}", "/p")
        os.utime(folder / f"e{k}" / cache.META, (1_000 + k, 1_000 + k))  # e0 the oldest
    assert cache.restore(folder / "e0", tmp_path / "use", "/p")  # used now: the newest
    assert cache.store(staging, folder / "last", "/p")  # one too many
    kept = sorted(p.name for p in folder.iterdir())
    assert len(kept) == cache.KEEP and "e0" in kept and "last" in kept and "e1" not in kept


def test_the_cache_folder_follows_the_environment(tmp_path: Path) -> None:
    assert cache.cache_folder({"TB4_INTERFACE_CACHE": "off", "HOME": "/h"}) is None
    assert cache.cache_folder({"TB4_INTERFACE_CACHE": str(tmp_path)}) == tmp_path
    assert cache.cache_folder({"XDG_CACHE_HOME": "/x", "HOME": "/h"}) == Path("/x/turtlebot4-navigator/interfaces")
    assert cache.cache_folder({"HOME": "/h"}) == Path("/h/.cache/turtlebot4-navigator/interfaces")


def test_a_lookup_that_cannot_read_its_inputs_builds_without_the_cache(tmp_path: Path) -> None:
    src = _source(tmp_path)
    (src / "pyproject.toml").write_text("[project]\nname = 'x'\n")  # no [build-system]
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "interface_cache.py"), "lookup", "--source-dir", str(src), "--distro",
         "kilted", "--packages", "nav2_msgs", "--compilers", "GNU 12", "--record", str(tmp_path / "inputs.json")],
        capture_output=True, text=True, timeout=30, env={**os.environ, "TB4_INTERFACE_CACHE": str(tmp_path / "c")},
    )  # fmt: skip
    assert done.returncode == 0 and done.stdout == "" and "building without the cache" in done.stderr


def test_cmake_restores_a_cached_build_instead_of_building(tmp_path: Path) -> None:
    """Configure once to learn this build's entry, put an entry there, configure a second build folder: it is
    restored into that build's staging folder, and no interface package is set up to build."""
    cmake = shutil.which("cmake", path=str(Path(sys.prefix) / "bin")) or shutil.which("cmake")
    assert cmake, "cmake is installed with the project's build tools"
    env = {**os.environ, "TB4_INTERFACE_CACHE": str(tmp_path / "cache")}

    def configure(build: Path) -> subprocess.CompletedProcess:
        return subprocess.run(
            [cmake, "-S", str(ROOT), "-B", str(build), "-G", "Ninja", f"-DPython3_EXECUTABLE={sys.executable}",
             "-DTB4_INTERFACE_PACKAGES=nav2_msgs", "-DSKBUILD_DATA_DIR=data", "-DSKBUILD_PLATLIB_DIR=platlib"],
            capture_output=True, text=True, timeout=120, env=env,
        )  # fmt: skip

    first = configure(tmp_path / "b1")
    assert first.returncode == 0, first.stderr
    assert "from the build cache" not in first.stdout
    assert "tb4_interface_cache_store" in (tmp_path / "b1" / "build.ninja").read_text()  # stored once built
    inputs = json.loads((tmp_path / "b1" / "interface-cache-inputs.json").read_text())
    entry = tmp_path / "cache" / shared_cache.cache_key(inputs)
    staged = _staging(tmp_path, "elsewhere", "/old/.venv")
    assert cache.store(staged, entry, "/old/.venv", inputs)
    second = configure(tmp_path / "b2")
    assert second.returncode == 0, second.stderr
    assert f"from the build cache {entry}" in second.stdout
    restored = tmp_path / "b2" / "interfaces-install" / "share" / "pkg" / "cmake" / "export.cmake"
    assert str(tmp_path / "b2" / "interfaces-install") in restored.read_text()
    assert (tmp_path / "b2" / "interface-cache-hit.txt").read_text().strip() == str(entry)
    ninja = (tmp_path / "b2" / "build.ninja").read_text()
    assert "nav2_msgs-configure" not in ninja and "tb4_interface_cache_store" not in ninja
