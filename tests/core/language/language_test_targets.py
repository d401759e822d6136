"""A test target for the executor: records the navigator calls it receives (plain Python, not a ROS mock).

It speaks the navigator's real types: results are `tb4.navigator.TaskResult` members (a plain Enum), goals are
started with the non-blocking Nav2 calls and followed with isTaskComplete()/getResult(), like TurtleBot4Navigator.
"""

from __future__ import annotations

import threading
from typing import Any

from tb4.navigator import TaskResult


class RecordingNavigator:
    """Records the calls it receives: the methods a program may reach, and dangerous ones that must never be.

    `results` maps a navigator method (goToPose, spin, ...) to the TaskResult its task ends with (SUCCEEDED when
    absent); `block_on_goal` keeps every task running until cancelTask(); `dock_ok` is what dock/undock return.
    """

    def __init__(
        self,
        block_on_goal: bool = False,
        results: dict[str, TaskResult] | None = None,
        dock_ok: bool = True,
        accept: bool = True,
    ) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.block_on_goal = block_on_goal
        self.results = results or {}
        self.dock_ok = dock_ok
        self.accept = accept
        self.cancelled = threading.Event()
        self.threads: set[str] = set()  # names of the threads that called us
        self.polls = 0
        self._done = threading.Event()
        self._done.set()
        self._result = TaskResult.UNKNOWN

    def _record(self, name: str, *args: Any) -> None:
        self.calls.append((name, args))
        self.threads.add(threading.current_thread().name)

    def _start(self, name: str, *args: Any) -> bool:
        self._record(name, *args)
        if not self.accept:
            return False
        self._result = self.results.get(name, TaskResult.SUCCEEDED)
        if self.block_on_goal:
            self._done.clear()
        return True

    def getPoseStamped(self, position: list[float], rotation: float) -> tuple[float, float, float]:  # noqa: N802
        return (float(position[0]), float(position[1]), float(rotation))

    def goToPose(self, pose: Any) -> bool:  # noqa: N802
        return self._start("goToPose", pose)

    def goThroughPoses(self, poses: Any) -> bool:  # noqa: N802
        return self._start("goThroughPoses", poses)

    def followWaypoints(self, poses: Any) -> bool:  # noqa: N802
        return self._start("followWaypoints", poses)

    def spin(self, spin_dist: float = 1.57, time_allowance: float = 10) -> bool:
        return self._start("spin", spin_dist, time_allowance)

    def backup(self, backup_dist: float = 0.15, backup_speed: float = 0.025, time_allowance: float = 10) -> bool:
        return self._start("backup", backup_dist, backup_speed, time_allowance)

    def driveOnHeading(self, dist: float = 0.15, speed: float = 0.025, time_allowance: float = 10) -> bool:  # noqa: N802
        return self._start("driveOnHeading", dist, speed, time_allowance)

    def isTaskComplete(self) -> bool:  # noqa: N802
        self.polls += 1
        return self._done.wait(0.01)  # like the real one: waits a little on the result event

    def getResult(self) -> TaskResult:  # noqa: N802
        return self._result if self._done.is_set() else TaskResult.UNKNOWN

    def cancelTask(self) -> None:  # noqa: N802
        self._record("cancelTask")
        if not self._done.is_set():
            self._result = TaskResult.CANCELED
            self._done.set()
        self.cancelled.set()

    def dock(self) -> bool:
        self._record("dock")
        return self.dock_ok

    def undock(self) -> bool:
        self._record("undock")
        return self.dock_ok

    def info(self, msg: str) -> None:
        self._record("info", msg)

    def warn(self, msg: str) -> None:
        self._record("warn", msg)

    def error(self, msg: str) -> None:
        self._record("error", msg)

    def debug(self, msg: str) -> None:
        self._record("debug", msg)

    # Dangerous methods a hostile program would like to reach.
    def destroyNode(self) -> None:  # noqa: N802
        self._record("destroyNode")

    def lifecycleShutdown(self) -> None:  # noqa: N802
        self._record("lifecycleShutdown")
