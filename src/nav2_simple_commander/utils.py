"""Upstream import path: `from nav2_simple_commander.utils import euler_to_quaternion`."""

from tb4.navigator.utils import euler_to_quaternion, find_os_processes, kill_os_processes, kill_process

__all__ = ["euler_to_quaternion", "find_os_processes", "kill_process", "kill_os_processes"]
