"""The machine-wide caches' common ground: where a cache lives and how old entries go (the interface build cache and
the wheel cache, each shared by every clone on the machine). Standard library only."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
from collections.abc import Callable
from pathlib import Path

__all__ = ["cache_folder", "cache_key", "store_entry", "prune"]


def cache_folder(variable: str, name: str, environ: dict[str, str] | None = None) -> Path | None:
    """The folder the environment variable `variable` names, else ${XDG_CACHE_HOME:-~/.cache}/turtlebot4-navigator/
    `name`; None when the variable says "off"."""
    env = os.environ if environ is None else environ
    chosen = env.get(variable, "").strip()
    if chosen.lower() in ("off", "0", "no", "false"):
        return None
    if chosen:
        return Path(chosen).expanduser()
    base = env.get("XDG_CACHE_HOME") or str(Path(env.get("HOME", "~")).expanduser() / ".cache")
    return Path(base) / "turtlebot4-navigator" / name


def cache_key(inputs: dict[str, object]) -> str:
    """An entry's name: a digest of everything that went into it."""
    return hashlib.sha256(json.dumps(inputs, sort_keys=True).encode()).hexdigest()[:32]


def store_entry(entry: Path, marker: str, meta: dict[str, object], fill: Callable[[Path], None], keep: int) -> bool:
    """Make `entry` complete or not at all: `fill` writes a temporary folder beside it, `meta` goes last into its
    `marker` file, and the folder is renamed into place (replacing an entry there: expired, or incomplete from a
    crash); then the cache is pruned to `keep` entries. False (nothing stored) when `fill` or the folder fails, or
    True if another clone stored the entry meanwhile."""
    temporary = entry.with_name(f".{entry.name}.{os.getpid()}")
    try:
        entry.parent.mkdir(parents=True, exist_ok=True)
        shutil.rmtree(temporary, ignore_errors=True)
        fill(temporary)
        (temporary / marker).write_text(json.dumps(meta, indent=1), encoding="utf-8")
        shutil.rmtree(entry, ignore_errors=True)
        temporary.rename(entry)  # fails if another clone stored it meanwhile: then theirs is kept
    except (OSError, RuntimeError) as exc:
        shutil.rmtree(temporary, ignore_errors=True)
        if not (entry / marker).is_file():
            print(f"{entry.parent.name} cache: nothing stored: {exc}", file=sys.stderr)
            return False
        return True
    prune(entry.parent, marker, keep)
    return True


def prune(folder: Path, marker: str, keep: int) -> None:
    """Keep the `keep` entries of `folder` whose `marker` file is newest; drop the temporary folders (.name) of
    stores that died over a day ago. An entry without its marker is incomplete and never counted."""
    entries = [p for p in folder.iterdir() if (p / marker).is_file()]
    entries.sort(key=lambda p: (p / marker).stat().st_mtime, reverse=True)
    for old in entries[keep:]:
        shutil.rmtree(old, ignore_errors=True)
    day_ago = time.time() - 86400
    for stale in folder.glob(".*"):
        if stale.is_dir() and stale.stat().st_mtime < day_ago:
            shutil.rmtree(stale, ignore_errors=True)
