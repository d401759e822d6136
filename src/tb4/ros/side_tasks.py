"""Tasks that run beside the nav core's one motion task, stepped by the simulator loop after every tick.

Route tracking only watches the robot (the client drives it along the route), and docking orchestrates motion
tasks of its own (navigation to the staging pose, the Create 3 dock): neither is the nav core's motion task, but
both must advance in sim time, in the loop thread, like everything else.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from tb4.ros.loop import LoopView, task_done

__all__ = ["SideTasks"]


class SideTasks:
    """Steps each added task with `step(now)` after every loop tick until it is done."""

    def __init__(self, loop: LoopView) -> None:
        self.loop = loop
        self._running: list[tuple[Any, Callable[[float], Any]]] = []
        loop.on_tick(self._step)
        loop.busy_while(lambda: bool(self._running))  # stepped every control period while one runs

    def add(self, task: Any, step: Callable[[float], Any] | None = None) -> Any:
        """Start stepping `task` (from the loop thread: call it inside a start callback); returns the task."""
        if not task_done(task):
            self._running.append((task, step or task.step))
        return task

    def running(self, kind: type) -> list[Any]:
        return [task for task, _ in self._running if isinstance(task, kind) and not task_done(task)]

    def _step(self, now: float) -> None:
        with self.loop.lock:
            keep = []
            for task, step in self._running:
                if not task_done(task):
                    step(now)
                if not task_done(task):
                    keep.append((task, step))
            self._running = keep
