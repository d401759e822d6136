"""Nav2 Simple Commander's utils (Kilted): euler_to_quaternion for building goal orientations, and the process
helpers its demos use to stop a Gazebo they started (find_os_processes, kill_process, kill_os_processes).

Same names, parameters and results as upstream; the process helpers read `ps` output like upstream does. They
only ever act on what the caller names: nothing here is used by the navigator itself.
"""

from __future__ import annotations

import os
import signal
import subprocess

from geometry_msgs.msg import Quaternion

from tb4.core import geometry
from tb4.navigator._validate import check_number

__all__ = ["euler_to_quaternion", "find_os_processes", "kill_process", "kill_os_processes"]


def euler_to_quaternion(roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Quaternion:
    """The quaternion of roll, pitch, yaw (radians, applied as Z-Y-X: yaw, then pitch, then roll)."""
    x, y, z, w = geometry.euler_to_quaternion(
        check_number(roll, "roll"), check_number(pitch, "pitch"), check_number(yaw, "yaw")
    )
    return Quaternion(x=x, y=y, z=z, w=w)


def find_os_processes(name: str) -> list[tuple[str, str]]:
    """(pid, command line) of every process whose command line starts with `name` (full lines: ps -ww)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty string, got {name!r}")
    listing = subprocess.run(["ps", "-ww", "-eo", "pid=,args="], capture_output=True, text=True, check=True).stdout
    found: list[tuple[str, str]] = []
    for line in listing.splitlines():
        pid, _, command = line.strip().partition(" ")
        command = command.strip()
        if pid.isdigit() and command.startswith(name):
            found.append((pid, command))
    return found


def kill_process(pid: str) -> None:
    """SIGKILL one process by its id; prints the outcome (as upstream) instead of raising."""
    try:
        os.kill(int(pid), signal.SIGKILL)
        print(f"Successfully killed process with PID: {pid}")
    except (OSError, ValueError, OverflowError) as exc:
        print(f"Failed to kill process with PID: {pid}. Error: {exc}")


def kill_os_processes(name: str) -> None:
    """SIGKILL every process whose command line starts with `name` (upstream's demos pass 'gz sim')."""
    processes = find_os_processes(name)
    if not processes:
        print(f"No processes found starting with {name}")
    for pid, _ in processes:
        kill_process(pid)
