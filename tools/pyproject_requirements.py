"""The requirement lists of pyproject.toml, read in one place: tools/install.sh installs them,
tools/interface_cache.py keys the interface build on the build's, and `make docs` installs the [docs] extra's.
Standard library only (it runs before anything is installed, on Python 3.10 too, which has no tomllib).

    python tools/pyproject_requirements.py build|all [PYPROJECT]      # one requirement per line
    python tools/pyproject_requirements.py build|all --distro jazzy [PYPROJECT]  # with Jazzy's ROS wheels
    python tools/pyproject_requirements.py extra NAME [PYPROJECT]     # one extra's requirements
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

__all__ = ["DISTROS", "requirements", "extra", "main"]

_PROJECT = "turtlebot4-navigator"  # the [all] extra names the others by the project's own name: no requirement
#: The ROS 2 distributions whose wheels an environment can be made of: Kilted's are the lists of [build-system] and
#: [project]; another one's replace their ros-* requirements ([tool.tb4.DISTRO]).
DISTROS = ("kilted", "jazzy")


def _block(text: str, pattern: str, what: str, source: Path) -> str:
    found = re.search(pattern, text, re.S)
    if found is None:
        raise ValueError(f"{source}: no {what} list")
    return found.group(1)


def requirements(pyproject: Path, which: str, distro: str = "kilted") -> list[str]:
    """`build`: [build-system] requires; `all`: those, then the project's dependencies and every extra's; each once,
    in that order. For a `distro` other than Kilted, the ros-* requirements of each list are replaced by that
    distribution's ([tool.tb4.DISTRO] build-requires and dependencies).

    Raises:
        ValueError: a list is missing, or `which` or `distro` is unknown.
    """
    if which not in ("build", "all"):
        raise ValueError(f"which must be 'build' or 'all', got {which!r}")
    if distro not in DISTROS:
        raise ValueError(f"distro must be one of {', '.join(DISTROS)}, got {distro!r}")
    text = pyproject.read_text(encoding="utf-8")
    blocks = [_block(text, r"\[build-system\]\s*requires\s*=\s*\[(.*?)\]", "[build-system] requires", pyproject)]
    if which == "all":
        blocks += [
            _block(text, r"\[project\][^\[]*?\ndependencies\s*=\s*\[(.*?)\]", "[project] dependencies", pyproject),
            _block(text, r"\[project\.optional-dependencies\](.*?)\n\[", "[project.optional-dependencies]", pyproject),
        ]
    found = [r for block in blocks for r in re.findall(r'"([^"]+)"', block)]
    if distro != "kilted":
        table = _block(text, rf"\[tool\.tb4\.{distro}\](.*?)(?:\n\[|\Z)", f"[tool.tb4.{distro}]", pyproject)
        lists = ["build-requires"] + (["dependencies"] if which == "all" else [])
        ros = [
            r
            for name in lists
            for r in re.findall(r'"([^"]+)"', _block(table, rf"(?m)^{name}\s*=\s*\[(.*?)\]", name, pyproject))
        ]
        found = ros + [r for r in found if not r.startswith("ros-")]
    return list(dict.fromkeys(r for r in found if not r.startswith(_PROJECT)))


def extra(pyproject: Path, name: str) -> list[str]:
    """The requirements of one extra of [project.optional-dependencies] (a `name = [...]` line or block)."""
    text = pyproject.read_text(encoding="utf-8")
    block = _block(text, r"\[project\.optional-dependencies\](.*?)\n\[", "[project.optional-dependencies]", pyproject)
    found = re.search(rf'^{re.escape(name)}\s*=\s*\[((?:"[^"]*"|[^"\]])*)\]', block, re.M)
    if found is None:
        raise ValueError(f"{pyproject}: no extra {name!r} in [project.optional-dependencies]")
    return re.findall(r'"([^"]+)"', found.group(1))


def main(argv: list[str]) -> int:
    if argv[:1] == ["extra"] and len(argv) in (2, 3):
        print("\n".join(extra(Path(argv[2] if len(argv) > 2 else "pyproject.toml"), argv[1])))
        return 0
    distro = "kilted"
    if len(argv) >= 3 and argv[1] == "--distro":
        distro = argv[2]
        argv = [argv[0], *argv[3:]]
    if len(argv) not in (1, 2) or argv[0] not in ("build", "all") or distro not in DISTROS:
        print(
            "usage: pyproject_requirements.py build|all [--distro kilted|jazzy] [PYPROJECT] | extra NAME [PYPROJECT]",
            file=sys.stderr,
        )
        return 2
    print("\n".join(requirements(Path(argv[1] if len(argv) > 1 else "pyproject.toml"), argv[0], distro)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
