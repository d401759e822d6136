"""Safe ROS 2 environment defaults, and a clear diagnosis when the ROS side of the install is broken.

DDS multicasts discovery on every network interface unless told otherwise; a laptop on a shared network would
announce (and accept) nodes from the whole LAN. We default to loopback unless the user chose explicitly.
"""

from __future__ import annotations

import importlib
import os
import sys
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "apply_safe_ros_defaults",
    "RosEnvironmentError",
    "check_ros_environment",
    "require_ros",
    "INTERFACE_MODULES",
    "share_directories",
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


def apply_safe_ros_defaults(environ: dict[str, str] | None = None) -> None:
    """Keep DDS on loopback unless the user set a discovery range (or the legacy localhost flag) explicitly; and
    NumPy's BLAS on one thread unless the user chose (BLAS_THREADS_DEFAULT says why)."""
    env = os.environ if environ is None else environ
    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in env and "ROS_LOCALHOST_ONLY" not in env:
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env.setdefault("OPENBLAS_NUM_THREADS", BLAS_THREADS_DEFAULT)


#: NumPy's OpenBLAS starts a thread per core when NumPy is imported, and that thread spins while it waits for work
#: after the import and after each BLAS call (perf shows it in blas_thread_server): a process that only imports
#: NumPy and makes a node spends nearly twice the CPU it needs, and so does every simulator, tutorial and script.
#: Our arrays are small (poses, scans, grids) and the hot loops are C kernels, so a second BLAS thread only takes
#: CPU from DDS, the simulator and the user's script. It applies to the processes started after it is set, and to
#: this one when NumPy is not imported yet.
BLAS_THREADS_DEFAULT = "1"


FASTDDS_PROFILE_VARIABLES = ("FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE")
SIMULATOR_DDS_PROFILE = Path(__file__).resolve().parent / "ros" / "fastdds_simulator.xml"


def apply_simulator_dds_profile(environ: dict[str, str] | None = None) -> None:
    """For the simulator's process, before its first node: announce it to DDS every 0.5 s, not every 3 s.

    A process started beside a running simulator sometimes goes unanswered by its first announcements and is then
    found only at the simulator's next periodic one, seconds later: a tutorial's first dock_status came that much
    late. Left alone when the user has a Fast DDS profile file of their own or another RMW.
    """
    env = os.environ if environ is None else environ
    if env.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp") != "rmw_fastrtps_cpp":
        return
    if any(name in env for name in FASTDDS_PROFILE_VARIABLES):
        return
    env["FASTDDS_DEFAULT_PROFILES_FILE"] = str(SIMULATOR_DDS_PROFILE)


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
    if missing:
        lines = [f"  - {c.module} (from {c.provider}): {c.error}" for c in missing]
        raise RosEnvironmentError(
            "The ROS 2 side of turtlebot4-navigator is not usable:\n" + "\n".join(lines) + f"\n{FIX_HINT}"
        )


def share_directories() -> list[Path]:
    """Where this environment's ROS packages keep their definitions (share/), the ones that win first.

    This environment's own prefix, then AMENT_PREFIX_PATH's, in order: an overlay (the Jazzy environment over the
    Kilted one, tools/venv_overlay.py, or a sourced workspace) lists itself before what it overlays.
    """
    prefixes = [sys.prefix, *(p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p)]
    return [Path(prefix) / "share" for prefix in dict.fromkeys(prefixes)]
