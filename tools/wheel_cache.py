"""Wheels of the project's requirements, kept in a folder shared by every clone on this machine, like pip's wheel cache.

Without it a fresh clone's install fetches every index page and every wheel from PyPI again (pip revalidates the
index pages it cached, and a pip without an HTTP cache has none), and those downloads are the most varying part of an
install. `pip wheel` fills a folder with a wheel for every requirement once per requirement set; installs then take
them from it without the network (pip install --no-index --find-links FOLDER). An entry older than MAX_AGE_DAYS is
fetched anew, so new releases are picked up.

The key is everything that decides which wheels pip picks: the requirements, the Python and platform, and pip's
configuration (its config files' settings, PIP_* variables and the constraint files they name).

TB4_WHEEL_CACHE: the cache folder (default ${XDG_CACHE_HOME:-~/.cache}/turtlebot4-navigator/wheels), or "off".
Standard library only. tools/install.sh calls

    python tools/wheel_cache.py PYTHON REQUIREMENT...

which prints the folder to install from (fetching it first when there is none), or nothing when the cache is off or
cannot be filled: the install then uses the index, as without the cache.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import shared_cache  # tools/, beside this file

__all__ = ["key_inputs", "entry_for", "fill", "main"]

FORMAT = 1  # the entry layout; a change makes every older entry a miss
META = "tb4-wheel-cache.json"  # written last into an entry: an entry without it is incomplete
KEEP = 4  # entries kept (about 250 MB each): a Kilted and a Jazzy environment, and one older of each
MAX_AGE_DAYS = 7.0
PYTHON_AND_PLATFORM = "import sys, sysconfig; print(sys.version, sysconfig.get_platform())"


def _run(python: str, *args: str, env: dict[str, str] | None = None) -> str:
    return subprocess.run([python, *args], capture_output=True, text=True, timeout=120, check=True, env=env).stdout


def key_inputs(python: str, requirements: list[str], environ: dict[str, str] | None = None) -> dict[str, object]:
    """What decides the wheels pip picks for `requirements` with `python`."""
    env = dict(os.environ if environ is None else environ)
    config = _run(python, "-m", "pip", "config", "list", env=env)
    pip_variables = {k: v for k, v in sorted(env.items()) if k.startswith("PIP_")}
    constraint_files = []
    for line in [*config.splitlines(), *(f"{k}={v}" for k, v in pip_variables.items())]:
        name, _, value = line.partition("=")
        if name.lower().endswith("constraint"):
            for path in value.strip().strip("'\"").split():
                text = Path(path).read_text(encoding="utf-8") if Path(path).is_file() else "(missing)"
                constraint_files.append((path, text))
    return {
        "format": FORMAT,
        "requirements": list(requirements),
        "python": _run(python, "-c", PYTHON_AND_PLATFORM, env=env).strip(),
        "pip_config": config,
        "pip_variables": pip_variables,
        "constraint_files": constraint_files,
    }


def entry_for(folder: Path, key: str, now: float | None = None) -> Path | None:
    """The complete entry for `key` younger than MAX_AGE_DAYS, or None."""
    meta = folder / key / META
    if not meta.is_file():
        return None
    age = (time.time() if now is None else now) - meta.stat().st_mtime
    return folder / key if age < MAX_AGE_DAYS * 86400 else None


def fill(python: str, requirements: list[str], entry: Path, inputs: dict[str, object]) -> bool:
    """`pip wheel` every requirement into `entry`, complete or not at all (replacing an expired entry), then prune the
    cache (shared_cache.store_entry). False (nothing stored) when pip or the folder fails."""

    def wheels(folder: Path) -> None:
        try:
            result = subprocess.run(
                [python, "-m", "pip", "wheel", "-q", "-w", str(folder), *requirements],
                capture_output=True,
                text=True,
                timeout=1800,
            )
        except subprocess.SubprocessError as exc:
            raise RuntimeError(f"pip wheel: {exc}") from None
        if result.returncode != 0:
            raise RuntimeError(f"pip wheel failed:\n{result.stderr[-2000:]}")

    return shared_cache.store_entry(entry, META, inputs, wheels, KEEP)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) < 2:
        print("usage: wheel_cache.py PYTHON REQUIREMENT...", file=sys.stderr)
        return 2
    python, requirements = args[0], args[1:]
    folder = shared_cache.cache_folder("TB4_WHEEL_CACHE", "wheels")
    if folder is None:
        return 0
    try:
        inputs = key_inputs(python, requirements)
    except (OSError, ValueError, subprocess.SubprocessError) as exc:  # no cache then, never a failed install
        print(f"wheel_cache: installing from the index: {exc}", file=sys.stderr)
        return 0
    entry = folder / shared_cache.cache_key(inputs)
    if entry_for(folder, entry.name) is None and not fill(python, requirements, entry, inputs):
        print("wheel_cache: installing from the index", file=sys.stderr)
        return 0
    print(entry)
    return 0


if __name__ == "__main__":
    sys.exit(main())
