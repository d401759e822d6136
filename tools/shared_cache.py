"""The machine-wide caches' common ground: where a cache lives and how old entries go (the interface build cache and
the wheel cache, each shared by every clone on the machine). Standard library only."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

__all__ = ["cache_folder", "prune"]


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
