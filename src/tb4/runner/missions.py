"""What `tb4 run` runs: one of our tutorials, a user's script file, or a user's module (`-m package.module`).

A user's mission is the same file that runs on the robot: it imports nothing of ours (upstream's
`nav2_simple_commander` and `turtlebot4_navigation` import paths are ours here, but that is the user's business).
Everything `tb4 run` can check before the simulator starts is checked here, so a typo costs no boot: the file
exists and compiles, the module can be found.
"""

from __future__ import annotations

import difflib
import importlib.util
import sys
from dataclasses import dataclass, field
from pathlib import Path

from tb4.tutorials import TUTORIALS, Tutorial

__all__ = ["Mission", "MissionError", "resolve_mission", "DEFAULT_WORLD"]

#: the world a user's mission runs in when --world does not say (the tutorials name their own)
DEFAULT_WORLD = "warehouse"

TUTORIAL, SCRIPT, MODULE = "tutorial", "script", "module"


class MissionError(ValueError):
    """The mission cannot run: no such tutorial, file or module, or a file that does not compile."""


@dataclass(frozen=True)
class Mission:
    """One thing to run under `tb4 run`.

    Attributes:
        name: a short name for run folders and titles (the tutorial's, the script's stem, the module's last part).
        kind: "tutorial", "script" or "module".
        target: the tutorial's name, the script's absolute path, or the module's dotted name.
        world: the world it runs in unless --world says otherwise.
        interactive: it reads the terminal (its stdin is passed on; progress is plain lines).
        robots: a fleet mission's robot count (robot1..robotN); 0 for one robot.
        waypoints: how many waypoints it follows, for the progress line (None: unknown).
        search_path: the folder a module is looked up from (the current one when `tb4 run` started).
    """

    name: str
    kind: str
    target: str
    world: str
    interactive: bool = False
    robots: int = 0
    waypoints: int | None = None
    search_path: str = field(default="", compare=False)

    def child_args(self) -> list[str]:
        """The arguments of `python -m tb4.runner.tutorial_start` that run this mission."""
        if self.kind == TUTORIAL:
            return [self.target]
        if self.kind == SCRIPT:
            return ["--script", self.target]
        return ["--module", self.target, "--path", self.search_path]


def _tutorial_mission(tutorial: Tutorial, world: str | None) -> Mission:
    return Mission(
        tutorial.name,
        TUTORIAL,
        tutorial.name,
        world or tutorial.world,
        interactive=tutorial.interactive,
        robots=tutorial.robots,
        waypoints=_waypoint_count(tutorial),
    )


def _waypoint_count(tutorial: Tutorial) -> int | None:
    module = tutorial.module()
    for name in ("WAYPOINTS", "POSES", "PATROL"):
        if hasattr(module, name):
            return len(getattr(module, name))
    return None


def _check_compiles(path: Path) -> None:
    try:
        source = path.read_bytes()
    except OSError as exc:
        raise MissionError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        compile(source, str(path), "exec", dont_inherit=True)
    except SyntaxError as exc:
        where = f"line {exc.lineno}" + (f", column {exc.offset}" if exc.offset else "")
        raise MissionError(f"{path} does not compile ({where}): {exc.msg}") from None
    except ValueError as exc:  # null bytes: not a source file
        raise MissionError(f"{path} is not Python source: {exc}") from None


def _script_path(target: str, cwd: Path) -> Path | None:
    """The file `target` names, if any: as given, or with `.py` added (`tb4 run my_mission`)."""
    for candidate in (target, f"{target}.py"):
        path = Path(candidate).expanduser()
        path = path if path.is_absolute() else cwd / path
        if path.is_file():
            return path.resolve()
        if path.exists() and candidate == target and not path.is_file():
            raise MissionError(f"{path} is not a file")
    return None


def _check_module(name: str, cwd: Path) -> None:
    """Find (without running) the module `python -m NAME` would run from `cwd`."""
    if not all(part.isidentifier() for part in name.split(".")):
        raise MissionError(f"{name!r} is not a module name (package.module)")
    sys.path.insert(0, str(cwd))
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError) as exc:
        raise MissionError(f"cannot find module {name!r}: {exc}") from None
    finally:
        sys.path.remove(str(cwd))
    if spec is None:
        raise MissionError(f"no module named {name!r} (looked in {cwd} and the installed packages)")
    if spec.submodule_search_locations is not None:
        main = importlib.util.find_spec(f"{name}.__main__")
        if main is None:
            raise MissionError(f"{name!r} is a package without a __main__ module")
    elif spec.origin and spec.origin.endswith(".py"):
        _check_compiles(Path(spec.origin))


def resolve_mission(
    target: str,
    *,
    module: bool = False,
    world: str | None = None,
    robots: int = 0,
    interactive: bool = False,
    cwd: Path | None = None,
) -> Mission:
    """The mission `tb4 run TARGET` (or `tb4 run -m TARGET`) names, checked before anything starts.

    A tutorial's name wins over a file of the same name without `.py` only when no such file exists; a path with
    a slash or a `.py` is always a script.

    Args:
        target: a tutorial name, a script path (with or without `.py`), or with `module`, a dotted module name.
        module: `target` is a module, run as `python -m` would.
        world: the world to run in (default: the tutorial's own, else DEFAULT_WORLD).
        robots: a fleet for a script or module: robot1..robotN (a tutorial has its own).
        interactive: pass the terminal's input to a script or module.
        cwd: the folder relative paths and modules are found from (default: the current one).

    Returns:
        The Mission.

    Raises:
        MissionError: no such tutorial, file or module, a file that does not compile, or --robots for a tutorial.
    """
    cwd = (cwd or Path.cwd()).resolve()
    if module:
        _check_module(target, cwd)
        name = target.rsplit(".", 1)[-1]
        return Mission(name, MODULE, target, world or DEFAULT_WORLD, interactive, robots, search_path=str(cwd))
    looks_like_path = "/" in target or target.endswith(".py") or target.startswith(".")
    if not looks_like_path and target in TUTORIALS and not (cwd / target).is_file():
        if robots:
            raise MissionError(f"{target} sets its own robots; --robots is for your own missions")
        return _tutorial_mission(TUTORIALS[target], world)
    path = _script_path(target, cwd)
    if path is None:
        if looks_like_path:
            raise MissionError(f"no such file: {target}")
        close = difflib.get_close_matches(target, TUTORIALS, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise MissionError(
            f"'{target}' is neither a tutorial nor a file{hint} (tb4 run --list shows the tutorials; a mission of "
            "your own is a path: tb4 run ./my_mission.py)"
        )
    _check_compiles(path)
    stem = path.stem if path.suffix == ".py" else path.name
    return Mission(stem, SCRIPT, str(path), world or DEFAULT_WORLD, interactive, robots)
