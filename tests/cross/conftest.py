"""The cross-distro stage's two environments: this interpreter's (make test runs the stage with the Jazzy environment,
ROS 2 Jazzy's own middleware) and its peer, TB4_CROSS_PEER_VENV (the Jazzy wire environment: Kilted's middleware with
Jazzy's nav2_msgs). A process of either is started with the environment of its own Python: the variables this
interpreter's start-up hooks set (the ROS wheels' library path, an overlay's paths) are left out, so the peer's hooks
set its own."""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from tb4.processes import ros_environment

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = Path(__file__).resolve().parent / "programs"
PEER_VARIABLE = "TB4_CROSS_PEER_VENV"
#: set by the ROS wheels' start-up hook (ros_wheels_bootstrapper) and an overlay's (tools/venv_overlay.py)
_HOOK_VARIABLES = ("_ROS_WHEELS_BOOTSTRAP_COMPLETE", "TB4_VENV_OVERLAY", "AMENT_PREFIX_PATH")


@dataclass(frozen=True)
class Side:
    """One environment of the pair: its Python, and a name for reports."""

    name: str
    python: str

    def command(self, *args: str) -> list[str]:
        """`python ARGS...` in this environment."""
        return [self.python, *args]

    def tb4(self, *args: str) -> list[str]:
        """`tb4 ARGS...` in this environment."""
        return [self.python, "-m", "tb4.cli.main", *args]


def _hook_path(path: Path) -> bool:
    """A library folder a start-up hook adds: an environment's lib/ or a ROS wheel's ros_*.libs."""
    resolved = path.resolve()
    return (
        resolved.is_relative_to(Path(sys.prefix).resolve())
        or (resolved.name.startswith("ros_") and resolved.name.endswith(".libs"))
        or (resolved.name == "lib" and (resolved.parent / "pyvenv.cfg").is_file())
    )


def own_environment(domain_id: int) -> dict[str, str]:
    """An environment for a process of either side: this session's domain, loopback discovery, and none of the paths
    this interpreter's start-up hooks put in place (each side's hooks set its own)."""
    env = ros_environment(domain_id)
    for name in _HOOK_VARIABLES:
        env.pop(name, None)
    kept = [part for part in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if part and not _hook_path(Path(part))]
    if kept:
        env["LD_LIBRARY_PATH"] = os.pathsep.join(kept)
    else:
        env.pop("LD_LIBRARY_PATH", None)
    return env


@pytest.fixture(scope="session")
def here() -> Side:
    return Side("this environment", sys.executable)


@pytest.fixture(scope="session")
def peer() -> Side:
    """The other environment of the pair (TB4_CROSS_PEER_VENV); the stage is skipped, saying so, without it."""
    value = os.environ.get(PEER_VARIABLE)
    if not value:
        pytest.skip(f"{PEER_VARIABLE} is not set: `make test-cross-distro` sets it (the Jazzy wire environment)")
    python = (ROOT / value).absolute() / "bin" / "python"
    if not python.exists():
        pytest.fail(f"{PEER_VARIABLE}={value}: no environment there ({python}); run `make install-jazzy-wire`")
    return Side(value, str(python))
