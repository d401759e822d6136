"""Safe ROS 2 environment defaults, and a clear diagnosis when the ROS side of the install is broken.

DDS multicasts discovery on every network interface unless told otherwise; a laptop on a shared network would
announce (and accept) nodes from the whole LAN. We default to loopback unless the user chose explicitly.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "apply_safe_ros_defaults",
    "apply_loopback_dds_profile",
    "apply_simulator_dds_profile",
    "discovery_is_loopback",
    "RosEnvironmentError",
    "check_ros_environment",
    "require_ros",
    "INTERFACE_MODULES",
    "share_directories",
    "Middleware",
    "installed_middleware",
    "middleware_problems",
    "fix_hint",
]

#: Modules our ROS side needs, with what provides them.
INTERFACE_MODULES: dict[str, str] = {
    "rclpy": "the ros-rclpy wheel",
    "nav2_msgs.action": "our interface packages (built from interfaces/ at install)",
    "irobot_create_msgs.action": "our interface packages (built from interfaces/ at install)",
    "tf2_msgs.msg": "our interface packages (built from interfaces/ at install)",
    "nav_msgs.msg": "the ros-nav-msgs wheel",
    "sensor_msgs.msg": "the ros-sensor-msgs wheel",
}

FIX_HINT = "Re-run `make install` (or `pip install -e .` in the project's .venv) and read the build output."
JAZZY_FIX_HINT = (
    "Re-run `make install-jazzy` (or `TB4_ROS_DISTRO=jazzy VENV=DIR bash tools/install.sh` for an environment of your "
    "own) and read the build output."
)
#: Written by tools/install.sh into a whole environment (not an overlay): the ROS 2 distribution whose wheels it holds.
DISTRO_FILE = "tb4-ros-distro"
#: Each ROS 2 distribution's releases of the middleware, by major version: rclpy, rmw_fastrtps_cpp and Fast DDS (whose
#: wheel is ros-fastrtps up to 2.x, ros-fastdds from 3.0). A distribution numbers its own releases of each.
DISTRO_MAJORS: dict[str, dict[str, str]] = {
    "jazzy": {"rclpy": "7", "rmw_fastrtps_cpp": "8", "fast_dds": "2"},
    "kilted": {"rclpy": "9", "rmw_fastrtps_cpp": "9", "fast_dds": "3"},
}


def apply_safe_ros_defaults(environ: dict[str, str] | None = None, fast_dds: str | None = None) -> None:
    """Keep DDS on loopback unless the user set a discovery range (or the legacy localhost flag) explicitly, and there
    carry DDS data over loopback UDP (apply_loopback_dds_profile); and NumPy's BLAS on one thread unless the user
    chose (BLAS_THREADS_DEFAULT says why).

    Args:
        environ: the environment to set (default: this process's).
        fast_dds: the Fast DDS version the profile is for (default: the installed one).
    """
    env = os.environ if environ is None else environ
    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in env and "ROS_LOCALHOST_ONLY" not in env:
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS_DEFAULT)
    apply_loopback_dds_profile(env, fast_dds)


#: NumPy's OpenBLAS starts a thread per core when NumPy is imported, and that thread spins while it waits for work
#: after the import and after each BLAS call (perf shows it in blas_thread_server): a process that only imports
#: NumPy and makes a node spends nearly twice the CPU it needs, and so does every simulator, tutorial and script.
#: Our arrays are small (poses, scans, grids) and the hot loops are C kernels, so a second BLAS thread only takes
#: CPU from DDS, the simulator and the user's script. It applies to the processes started after it is set, and to
#: this one when NumPy is not imported yet.
BLAS_THREADS_DEFAULT = "1"


FASTDDS_PROFILE_VARIABLES = ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE")
_PROFILE_FOLDER = Path(__file__).resolve().parent / "ros"
SIMULATOR_DDS_PROFILE = _PROFILE_FOLDER / "fastdds_simulator.xml"
SIMULATOR_DDS_PROFILE_FAST_DDS_2 = _PROFILE_FOLDER / "fastdds2_simulator.xml"
SIMULATOR_LOOPBACK_DDS_PROFILE = _PROFILE_FOLDER / "fastdds_simulator_loopback.xml"
SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2 = _PROFILE_FOLDER / "fastdds2_simulator_loopback.xml"
#: Every other process of ours under loopback discovery; Fast DDS 2 and 3 read it alike.
LOOPBACK_DDS_PROFILE = _PROFILE_FOLDER / "fastdds_loopback.xml"
_OUR_DDS_PROFILES = frozenset(
    path.name
    for path in (
        SIMULATOR_DDS_PROFILE,
        SIMULATOR_DDS_PROFILE_FAST_DDS_2,
        SIMULATOR_LOOPBACK_DDS_PROFILE,
        SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2,
        LOOPBACK_DDS_PROFILE,
    )
)


def _is_ours(profile: str) -> bool:
    """Whether a profile variable names one of our files, from this install or another one (a Jazzy environment's
    process started by a Kilted one's)."""
    path = Path(profile)
    return path.name in _OUR_DDS_PROFILES and path.parent.name == "ros" and path.parent.parent.name == "tb4"


def discovery_is_loopback(environ: Mapping[str, str] | None = None) -> bool:
    """Whether ROS 2 discovers other processes on this machine only, as rcl reads the variables: a
    ROS_AUTOMATIC_DISCOVERY_RANGE of LOCALHOST or of a value rcl does not know (it warns and assumes localhost; the
    names are case-sensitive), or, with no range set, the legacy ROS_LOCALHOST_ONLY=1."""
    env = os.environ if environ is None else environ
    if env.get("ROS_AUTOMATIC_DISCOVERY_RANGE", ""):
        return env["ROS_AUTOMATIC_DISCOVERY_RANGE"] not in ("OFF", "SUBNET", "SYSTEM_DEFAULT")
    return env.get("ROS_LOCALHOST_ONLY", "") == "1"


def _profile_variable(fast_dds: str | None) -> str:
    """The variable Fast DDS `fast_dds` (a version; default the installed one) reads its default profile file from:
    Fast DDS 2 (Jazzy) reads FASTRTPS_DEFAULT_PROFILES_FILE only."""
    version = installed_middleware().fast_dds if fast_dds is None else fast_dds
    return FASTDDS_PROFILE_VARIABLES[1] if version.split(".")[0] in ("1", "2") else FASTDDS_PROFILE_VARIABLES[0]


def _take_profile_variables(env: MutableMapping[str, str]) -> bool:
    """Clear the profile variables when they name our own files (a process of ours started this one, perhaps of the
    other Fast DDS), so the caller can set its own; False, touching nothing, when the user set one or another RMW
    is in use."""
    if env.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") != "rmw_fastrtps_cpp":
        return False
    if any(not _is_ours(env[name]) for name in FASTDDS_PROFILE_VARIABLES if name in env):
        return False
    for name in FASTDDS_PROFILE_VARIABLES:
        env.pop(name, None)
    return True


def apply_loopback_dds_profile(environ: MutableMapping[str, str] | None = None, fast_dds: str | None = None) -> None:
    """Under loopback discovery, have this process's DDS readers (and its children's) take their data over UDP on
    127.0.0.1 instead of shared memory (ros/fastdds_loopback.xml says why). Left alone when the user has a Fast DDS
    profile file of their own, discovery reaches beyond this machine, or another RMW is in use.

    Args:
        environ: the environment to set (default: this process's); a process reads it when it creates its first
            node, so set it before rclpy.init.
        fast_dds: the Fast DDS version the profile is for (default: the installed one).
    """
    env = os.environ if environ is None else environ
    if discovery_is_loopback(env) and _take_profile_variables(env):
        env[_profile_variable(fast_dds)] = str(LOOPBACK_DDS_PROFILE)


def simulator_dds_profile(fast_dds: str, *, loopback: bool) -> tuple[str, Path]:
    """The variable Fast DDS `fast_dds` (a version) reads its default profile file from, and our simulator's file
    for it: Fast DDS 2 (Jazzy) names some elements otherwise; under loopback discovery (`loopback`) the file also
    keeps DDS data off shared memory."""
    variable = _profile_variable(fast_dds)
    if variable == FASTDDS_PROFILE_VARIABLES[1]:
        return variable, SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2 if loopback else SIMULATOR_DDS_PROFILE_FAST_DDS_2
    return variable, SIMULATOR_LOOPBACK_DDS_PROFILE if loopback else SIMULATOR_DDS_PROFILE


def apply_simulator_dds_profile(environ: dict[str, str] | None = None, fast_dds: str | None = None) -> None:
    """For the simulator's process, before its first node: announce it to DDS every 0.5 s, not every 3 s, have
    its reliable writers send heartbeats every 0.1 s, (Fast DDS 3) propagate no types, and under loopback discovery
    take DDS data over loopback UDP (see the profile files).

    A process started beside a running simulator sometimes goes unanswered by its first announcements and is then
    found only at the simulator's next periodic one, seconds later: a tutorial's first dock_status came that much
    late. Left alone when the user has a Fast DDS profile file of their own or another RMW; replaces ours (the
    loopback profile a tb4 command sets for the processes it starts).

    Args:
        environ: the environment to set (default: this process's).
        fast_dds: the Fast DDS version the profile is for (default: the installed one).
    """
    env = os.environ if environ is None else environ
    if not _take_profile_variables(env):
        return
    variable, path = simulator_dds_profile(
        installed_middleware().fast_dds if fast_dds is None else fast_dds, loopback=discovery_is_loopback(env)
    )
    env[variable] = str(path)


class RosEnvironmentError(RuntimeError):
    """The ROS 2 side of the installation is incomplete; the message says what is missing and how to fix it."""


@dataclass(frozen=True)
class ModuleCheck:
    module: str
    provider: str
    ok: bool
    error: str = ""


def check_ros_environment() -> list[ModuleCheck]:
    """Try to import every module our ROS side needs; never raises."""
    results = []
    for module, provider in INTERFACE_MODULES.items():
        try:
            importlib.import_module(module)
        except Exception as exc:  # an ImportError, or an OSError from a missing shared library
            results.append(ModuleCheck(module, provider, False, f"{type(exc).__name__}: {exc}"))
        else:
            results.append(ModuleCheck(module, provider, True))
    return results


def require_ros() -> None:
    """Raise RosEnvironmentError naming every missing piece, instead of a traceback from deep inside rclpy."""
    missing = [c for c in check_ros_environment() if not c.ok]
    mixed = middleware_problems()
    if missing or mixed:
        lines = [f"  - {c.module} (from {c.provider}): {c.error}" for c in missing] + [f"  - {p}" for p in mixed]
        raise RosEnvironmentError(
            "The ROS 2 side of turtlebot4-navigator is not usable:\n" + "\n".join(lines) + f"\n{fix_hint()}"
        )


def share_directories() -> list[Path]:
    """Where this environment's ROS packages keep their definitions (share/), the ones that win first.

    This environment's own prefix, then AMENT_PREFIX_PATH's, in order: an overlay (the Jazzy environment over the
    Kilted one, tools/venv_overlay.py, or a sourced workspace) lists itself before what it overlays.
    """
    prefixes = [sys.prefix, *(p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p)]
    return [Path(prefix) / "share" for prefix in dict.fromkeys(prefixes)]


@dataclass(frozen=True)
class Middleware:
    """The ROS 2 middleware an environment holds: its wheels' versions ("" where a wheel is missing), the distribution
    tools/install.sh made it for ("" for an overlay or an environment made otherwise) and the one rclpy belongs to."""

    rclpy: str
    rmw_fastrtps_cpp: str
    fast_dds: str
    made_for: str
    distro: str

    def describe(self) -> str:
        """One line: the distribution, then each wheel's version."""
        versions = ", ".join(
            f"{name} {version or 'missing'}"
            for name, version in (
                ("rclpy", self.rclpy),
                ("rmw_fastrtps_cpp", self.rmw_fastrtps_cpp),
                ("Fast DDS", self.fast_dds),
            )
        )
        return f"ROS 2 {self.distro.capitalize() if self.distro else 'unknown'} ({versions})"


def _installed_versions() -> dict[str, str]:
    """{distribution name, lower case with underscores: version} of what is on sys.path, read off the .dist-info
    folders' names: importlib.metadata's look-up reads every distribution's metadata (about 0.4 s in an environment
    of ours), and every tb4 process checks (require_ros)."""
    found: dict[str, str] = {}
    for entry in sys.path:
        try:
            names = os.listdir(entry or ".")
        except OSError:
            continue
        for folder in names:
            if folder.endswith(".dist-info") and "-" in folder:
                stem, _, version = folder[: -len(".dist-info")].partition("-")
                found.setdefault(stem.lower(), version)
    return found


def _made_for() -> str:
    """The distribution tools/install.sh made this environment for, or "" (an overlay, or made otherwise)."""
    path = Path(sys.prefix) / DISTRO_FILE
    return path.read_text(encoding="utf-8").strip() if path.is_file() else ""


def installed_middleware() -> Middleware:
    """The middleware this environment holds, read from the installed wheels' metadata (nothing is imported)."""
    versions = _installed_versions()
    rclpy = versions.get("ros_rclpy", "")
    major = rclpy.split(".")[0]
    distro = next((name for name, majors in DISTRO_MAJORS.items() if majors["rclpy"] == major), "")
    fast_dds = versions.get("ros_fastdds") or versions.get("ros_fastrtps", "")
    return Middleware(rclpy, versions.get("ros_rmw_fastrtps_cpp", ""), fast_dds, _made_for(), distro)


def middleware_problems(middleware: Middleware | None = None) -> list[str]:
    """Why this environment's middleware is not one distribution's whole set, one sentence each (none when it is):
    a wheel of another distribution than rclpy's (an install that stopped half way, or a pip run by hand), or rclpy of
    another distribution than the environment was made for."""
    mw = installed_middleware() if middleware is None else middleware
    problems = []
    if mw.made_for and mw.distro != mw.made_for:
        found = f"rclpy {mw.rclpy}" if mw.rclpy else "no rclpy"
        problems.append(f"this environment was made for ROS 2 {mw.made_for.capitalize()} but holds {found}")
    if mw.distro:
        majors = DISTRO_MAJORS[mw.distro]
        for name, version in (("rmw_fastrtps_cpp", mw.rmw_fastrtps_cpp), ("fast_dds", mw.fast_dds)):
            if version and version.split(".")[0] != majors[name]:
                label = "Fast DDS" if name == "fast_dds" else name
                problems.append(
                    f"{label} {version} is not ROS 2 {mw.distro.capitalize()}'s (rclpy {mw.rclpy} is): "
                    "the environment mixes two distributions' wheels"
                )
    return problems


def fix_hint() -> str:
    """What to run to repair this environment: the install of the distribution it was made for."""
    return JAZZY_FIX_HINT if _made_for() == "jazzy" else FIX_HINT
