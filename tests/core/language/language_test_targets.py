"""A test target for the executor: records the navigator calls it receives (plain Python, not a ROS mock)."""

from __future__ import annotations

import threading
from typing import Any


class RecordingNavigator:
    """Records the calls it receives: the methods a program may reach, and dangerous ones that must never be."""

    def __init__(self, block_on_goal: bool = False) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.block_on_goal = block_on_goal
        self.cancelled = threading.Event()

    def _record(self, name: str, *args: Any) -> None:
        self.calls.append((name, args))

    def getPoseStamped(self, position: list[float], rotation: float) -> tuple[float, float, float]:  # noqa: N802
        return (float(position[0]), float(position[1]), float(rotation))

    def startToPose(self, pose: Any) -> None:  # noqa: N802
        self._record("startToPose", pose)
        if self.block_on_goal:
            self.cancelled.wait(30.0)

    def startThroughPoses(self, poses: Any) -> None:  # noqa: N802
        self._record("startThroughPoses", poses)

    def startFollowWaypoints(self, poses: Any) -> None:  # noqa: N802
        self._record("startFollowWaypoints", poses)

    def dock(self) -> None:
        self._record("dock")

    def undock(self) -> None:
        self._record("undock")

    def spin(self, spin_dist: float = 1.57, time_allowance: float = 10) -> bool:
        self._record("spin", spin_dist, time_allowance)
        return True

    def backup(self, backup_dist: float = 0.15, backup_speed: float = 0.025, time_allowance: float = 10) -> bool:
        self._record("backup", backup_dist, backup_speed, time_allowance)
        return True

    def driveOnHeading(self, dist: float = 0.15, speed: float = 0.025, time_allowance: float = 10) -> bool:  # noqa: N802
        self._record("driveOnHeading", dist, speed, time_allowance)
        return True

    def isTaskComplete(self) -> bool:  # noqa: N802
        return True

    def cancelTask(self) -> None:  # noqa: N802
        self._record("cancelTask")
        self.cancelled.set()

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
