"""The wheel cache (tools/wheel_cache.py): its key follows what decides pip's choice of wheels, an entry is stored
whole or not at all and expires, the cache prunes to its last entries, and a cache that is off or cannot be filled
leaves the install to the package index. A stand-in Python answers the pip commands the cache runs."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tool_modules import load_tool

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[2]
wheel_cache = load_tool("wheel_cache")
shared_cache = load_tool("shared_cache")

STAND_IN = """#!/bin/sh
# a stand-in for "python -m pip ..." and "python -c ...": what the wheel cache asks of the environment's Python
case "$1 $2 $3" in
  "-m pip config")
    echo "global.find-links='/opt/wheels'"
    [ -n "$STAND_IN_CONSTRAINT" ] && echo "global.constraint='$STAND_IN_CONSTRAINT'"
    exit 0 ;;
  "-m pip wheel")
    [ -n "$STAND_IN_FAIL" ] && { echo "no network" >&2; exit 1; }
    dir=$6; mkdir -p "$dir"; shift 6
    for r in "$@"; do : > "$dir/$(echo "$r" | tr -cd 'a-z')-1.0-py3-none-any.whl"; done
    exit 0 ;;
esac
[ "$1" = "-c" ] && { echo "3.11.7 linux-x86_64"; exit 0; }
exit 2
"""


@pytest.fixture
def python(tmp_path: Path) -> str:
    path = tmp_path / "python"
    path.write_text(STAND_IN)
    path.chmod(0o755)
    return str(path)


def _key(python: str, requirements: list[str], env: dict[str, str]) -> str:
    return shared_cache.cache_key(wheel_cache.key_inputs(python, requirements, env))


def test_key_follows_requirements_pip_settings_and_constraint_files(python: str, tmp_path: Path) -> None:
    base = {"PATH": os.environ["PATH"]}
    key = _key(python, ["numpy>=1.26"], base)
    assert _key(python, ["numpy>=1.26"], {**base, "UNRELATED": "1"}) == key
    assert _key(python, ["numpy>=1.27"], base) != key
    assert _key(python, ["numpy>=1.26"], {**base, "PIP_INDEX_URL": "https://example.org/simple"}) != key
    constraints = tmp_path / "constraints.txt"
    constraints.write_text("numpy<2\n")
    with_file = _key(python, ["numpy>=1.26"], {**base, "STAND_IN_CONSTRAINT": str(constraints)})
    assert with_file != key
    constraints.write_text("numpy<3\n")
    assert _key(python, ["numpy>=1.26"], {**base, "STAND_IN_CONSTRAINT": str(constraints)}) != with_file


def test_fill_stores_a_complete_entry_that_expires(python: str, tmp_path: Path) -> None:
    folder = tmp_path / "wheels"
    entry = folder / "k1"
    assert wheel_cache.entry_for(folder, "k1") is None
    assert wheel_cache.fill(python, ["numpy>=1.26", "rich"], entry, {"format": 1})
    assert sorted(p.name for p in entry.glob("*.whl")) == ["numpy-1.0-py3-none-any.whl", "rich-1.0-py3-none-any.whl"]
    assert wheel_cache.entry_for(folder, "k1") == entry
    later = time.time() + wheel_cache.MAX_AGE_DAYS * 86400 + 1
    assert wheel_cache.entry_for(folder, "k1", now=later) is None  # expired: fetched anew
    assert wheel_cache.fill(python, ["rich"], entry, {"format": 1})  # replaces the expired entry
    assert [p.name for p in entry.glob("*.whl")] == ["rich-1.0-py3-none-any.whl"]
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # no temporary folder left


def test_a_failed_fill_stores_nothing(python: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("STAND_IN_FAIL", "1")
    folder = tmp_path / "wheels"
    assert not wheel_cache.fill(python, ["numpy"], folder / "k1", {})
    assert wheel_cache.entry_for(folder, "k1") is None
    assert list(folder.iterdir()) == []


def test_prunes_to_the_newest_entries(python: str, tmp_path: Path) -> None:
    folder = tmp_path / "wheels"
    for i in range(wheel_cache.KEEP + 2):
        assert wheel_cache.fill(python, ["numpy"], folder / f"k{i}", {})
        meta = folder / f"k{i}" / wheel_cache.META
        os.utime(meta, (time.time() - 100 + i, time.time() - 100 + i))
    assert wheel_cache.fill(python, ["numpy"], folder / "new", {})
    kept = sorted(p.name for p in folder.iterdir())
    assert len(kept) == wheel_cache.KEEP and "new" in kept


def _main(python: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(ROOT / "tools" / "wheel_cache.py"), python, "numpy>=1.26"],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_main_prints_the_folder_to_install_from_or_nothing(python: str, tmp_path: Path) -> None:
    folder = tmp_path / "cache"
    first = _main(python, {"TB4_WHEEL_CACHE": str(folder)})
    assert first.returncode == 0, first.stderr
    entry = Path(first.stdout.strip())
    assert entry.parent == folder and (entry / "numpy-1.0-py3-none-any.whl").is_file()
    again = _main(python, {"TB4_WHEEL_CACHE": str(folder), "STAND_IN_FAIL": "1"})  # a hit: no pip wheel
    assert again.returncode == 0 and again.stdout.strip() == str(entry)
    off = _main(python, {"TB4_WHEEL_CACHE": "off"})
    assert off.returncode == 0 and off.stdout == ""
    failing = _main(python, {"TB4_WHEEL_CACHE": str(tmp_path / "other"), "STAND_IN_FAIL": "1"})
    assert failing.returncode == 0 and failing.stdout == "" and "from the index" in failing.stderr


def test_hostile_settings_leave_the_install_to_the_index(python: str, tmp_path: Path) -> None:
    binary = tmp_path / "constraints.bin"
    binary.write_bytes(b"\xff\xfe\x00numpy<2\x80")  # a constraint file that is no text
    unreadable = _main(python, {"TB4_WHEEL_CACHE": str(tmp_path / "cache"), "STAND_IN_CONSTRAINT": str(binary)})
    assert unreadable.returncode == 0 and unreadable.stdout == "", unreadable.stderr
    assert "from the index" in unreadable.stderr and "Traceback" not in unreadable.stderr
    not_a_folder = tmp_path / "a-file"
    not_a_folder.write_text("in the way\n")  # TB4_WHEEL_CACHE names a file
    blocked = _main(python, {"TB4_WHEEL_CACHE": str(not_a_folder)})
    assert blocked.returncode == 0 and blocked.stdout == "" and "Traceback" not in blocked.stderr
    assert not_a_folder.read_text() == "in the way\n"
