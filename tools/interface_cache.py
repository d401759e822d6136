"""A cache of our built ROS interface packages, shared by every clone on this machine, like ccache or pip's wheel cache.

Building tf2_msgs, geographic_msgs, irobot_create_msgs and nav2_msgs (or, for the Jazzy overlay, Jazzy's nav2_msgs)
is the largest part of an install. The staged result of a build (CMakeLists.txt's interfaces-install folder) is kept
under a key made of everything that goes into it: every interface definition and build file, the wire format, the
packages built, the Python, the compilers, and the versions of the build's Python distributions (the ROS wheels with
the generators, numpy). A later build with the same key copies the entry instead of building, and rewrites the few
text files that name the folders it was built in (CMake exports and the ament index).

TB4_INTERFACE_CACHE: the cache folder (default ${XDG_CACHE_HOME:-~/.cache}/turtlebot4-navigator/interfaces), or
"off". Standard library only (it runs inside the build). CMakeLists.txt calls:

    python tools/interface_cache.py lookup --source-dir DIR --distro D --packages "a;b" --compilers TEXT
    python tools/interface_cache.py restore ENTRY STAGING --prefix PREFIX
    python tools/interface_cache.py store STAGING ENTRY --prefix PREFIX
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import importlib.metadata
import json
import os
import platform
import re
import shutil
import sys
import sysconfig
from pathlib import Path

import shared_cache  # tools/, beside this file
from pyproject_requirements import DISTROS, requirements

__all__ = ["cache_folder", "build_distributions", "restore", "store", "main"]

FORMAT = 1  # the entry layout; a change makes every older entry a miss
META = "tb4-interface-cache.json"  # written last into an entry: an entry without it is incomplete
KEEP = 8  # entries kept, the most recently used (a Kilted or Jazzy entry is about 50 MB, a Jazzy overlay's 15 MB)
_REQUIREMENT_NAME = re.compile(r"^\s*([A-Za-z0-9][A-Za-z0-9._-]*)")


def cache_folder(environ: dict[str, str] | None = None) -> Path | None:
    """The cache folder, or None when TB4_INTERFACE_CACHE is "off"."""
    return shared_cache.cache_folder("TB4_INTERFACE_CACHE", "interfaces", environ)


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _needed(requirement: str) -> str | None:
    """The normalized name a requirement line pulls in here, or None: an extra's, or one whose environment marker is
    false for this Python (e.g. `typing-extensions; python_version < '3.11'`). Without `packaging` (it comes with
    scikit-build-core, a build requirement) only extras are left out."""
    try:
        from packaging.requirements import InvalidRequirement, Requirement
    except ImportError:
        match = _REQUIREMENT_NAME.match(requirement)
        extra = "extra ==" in requirement.replace('"', "").replace("'", "")
        return None if match is None or extra else _normalized(match.group(1))
    try:
        parsed = Requirement(requirement)
    except InvalidRequirement:
        return None
    if parsed.marker is not None and not parsed.marker.evaluate({"extra": ""}):
        return None
    return _normalized(parsed.name)


def build_distributions(roots: list[str]) -> list[str]:
    """`name==version` of every installed distribution the build requirements pull in on this Python (their closure),
    sorted: the generators and type support headers come from these. A requirement not installed is left out. Only
    what the first install step put in place counts, so the key does not depend on how far the second pip, running
    beside the build, has got."""
    seen: dict[str, str] = {}
    todo = [name for r in roots if (name := _needed(r)) is not None]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        try:
            dist = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        seen[name] = dist.version
        todo.extend(needed for r in dist.requires or [] if (needed := _needed(r)) is not None)
    return sorted(f"{name}=={version}" for name, version in seen.items())


def _tree_digest(folder: Path) -> str:
    """Every file under `folder` but documentation (*.md) and bytecode, by path and content."""
    digest = hashlib.sha256()
    files = (p for p in folder.rglob("*") if p.is_file() and p.suffix != ".md" and "__pycache__" not in p.parts)
    for path in sorted(files):
        digest.update(path.relative_to(folder).as_posix().encode() + b"\0")
        digest.update(hashlib.sha256(path.read_bytes()).digest())
    return digest.hexdigest()


def key_inputs(source_dir: Path, distro: str, packages: list[str], compilers: str) -> dict[str, object]:
    """Everything the staged build depends on (see the module's docstring)."""
    return {
        "format": FORMAT,
        "distro": distro,
        "packages": sorted(packages),
        "interfaces": _tree_digest(source_dir / "interfaces"),
        "recipe": hashlib.sha256((source_dir / "CMakeLists.txt").read_bytes()).hexdigest(),
        "python": [sys.version, sysconfig.get_config_var("EXT_SUFFIX"), platform.machine()],
        "compilers": compilers,
        # whichever distribution's build wheels this environment holds (Jazzy's nav2_msgs is built with Kilted's
        # rosidl in an overlay of the Kilted environment, with Jazzy's own in a genuine Jazzy environment)
        "distributions": build_distributions(
            [r for name in DISTROS for r in requirements(source_dir / "pyproject.toml", "build", name)]
        ),
    }


def _text_files(folder: Path):
    for path in folder.rglob("*"):
        if path.is_file() and not path.is_symlink() and "__pycache__" not in path.parts and path.suffix != ".so":
            yield path


def restore(entry: Path, staging: Path, prefix: str) -> bool:
    """Copy a complete entry into `staging` (replacing what is there), naming this build's folders where the entry
    named the ones it was built in. False (and `staging` untouched) when the entry is missing or incomplete."""
    try:
        meta = json.loads((entry / META).read_text(encoding="utf-8"))
        old = {str(meta["staging"]): str(staging), str(meta["prefix"]): prefix}
    except (OSError, ValueError, KeyError, TypeError):
        return False
    partial = staging.with_name(staging.name + ".restoring")
    shutil.rmtree(partial, ignore_errors=True)
    try:
        shutil.copytree(entry, partial, symlinks=True, ignore=shutil.ignore_patterns(META))
    except OSError:
        shutil.rmtree(partial, ignore_errors=True)
        return False
    replacements = sorted(((k.encode(), v.encode()) for k, v in old.items() if k != v), key=lambda kv: -len(kv[0]))
    for path in _text_files(partial):
        data = path.read_bytes()
        if b"\0" in data[:8192] or not any(k in data for k, _ in replacements):
            continue
        for before, after in replacements:
            data = data.replace(before, after)
        path.write_bytes(data)
    shutil.rmtree(staging, ignore_errors=True)
    partial.rename(staging)
    with contextlib.suppress(OSError):  # a cache we may only read is used all the same
        os.utime(entry / META)  # recently used: kept by the pruning
    return True


def store(staging: Path, entry: Path, prefix: str, inputs: dict[str, object] | None = None) -> bool:
    """Copy `staging` into the cache as `entry`, complete or not at all, then prune the cache to the KEEP most
    recently used entries (shared_cache.store_entry). False (nothing stored) on any error."""
    if (entry / META).is_file():
        return True
    meta = {"staging": str(staging), "prefix": prefix, "inputs": inputs or {}}
    return shared_cache.store_entry(
        entry, META, meta, lambda folder: shutil.copytree(staging, folder, symlinks=True), KEEP
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=(__doc__ or "").split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    lookup = sub.add_parser("lookup", help="print this build's entry folder (nothing when the cache is off)")
    lookup.add_argument("--source-dir", type=Path, required=True)
    lookup.add_argument("--distro", required=True)
    lookup.add_argument("--packages", required=True, help="a CMake list: a;b")
    lookup.add_argument("--compilers", required=True)
    lookup.add_argument("--record", type=Path, required=True, help="where to write the key's inputs, for store")
    restore_command = sub.add_parser("restore", help="copy ENTRY into STAGING (exit 1: no complete entry)")
    restore_command.add_argument("entry", type=Path)
    restore_command.add_argument("staging", type=Path)
    restore_command.add_argument("--prefix", required=True)
    store_command = sub.add_parser("store", help="copy STAGING into the cache as ENTRY (never fails the build)")
    store_command.add_argument("staging", type=Path)
    store_command.add_argument("entry", type=Path)
    store_command.add_argument("--prefix", required=True)
    store_command.add_argument("--record", type=Path, required=True, help="the inputs lookup wrote")
    args = parser.parse_args(argv)
    if args.command == "lookup":
        folder = cache_folder()
        if folder is None:
            return 0
        packages = [p for p in args.packages.split(";") if p]
        try:
            inputs = key_inputs(args.source_dir, args.distro, packages, args.compilers)
            args.record.write_text(json.dumps(inputs, indent=1), encoding="utf-8")
        except (OSError, ValueError) as exc:  # no cache then, never a failed install
            print(f"interface_cache: building without the cache: {exc}", file=sys.stderr)
            return 0
        print(folder / shared_cache.cache_key(inputs))
        return 0
    if args.command == "restore":
        return 0 if restore(args.entry, args.staging, args.prefix) else 1
    try:
        inputs = json.loads(args.record.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        inputs = {}
    if not store(args.staging, args.entry, args.prefix, inputs):
        message = f"could not store the build in {args.entry}; the install goes on without it"
        print(f"interface_cache: {message}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
