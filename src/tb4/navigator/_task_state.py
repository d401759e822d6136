"""Following and ending the running tasks. Upstream methods here: cancelTask, isTaskComplete, getFeedback,
getResult (plus getTaskStatusName, ours).

Both call styles work: Kilted's `isTaskComplete(task=t)` / `getFeedback(task=t)` with the RunningTask a method
returned, and Jazzy's/Humble's `isTaskComplete()` / `getFeedback()`. Only COMPUTE_AND_TRACK_ROUTE selects the route
task; every other value (and no argument) selects the main task, as upstream does.

Difference from upstream: `isTaskComplete(task=None)` (the task method returned None: the goal was rejected)
answers True, so `while not isTaskComplete(task=t)` ends; upstream answered False forever. getResult() then reads
UNKNOWN and getTaskError() gives the rejection.
"""

from __future__ import annotations

from typing import Any

from tb4.navigator._base import NavigatorBase
from tb4.navigator._task_client import TaskSlot
from tb4.navigator.results import RunningTask, TaskResult, status_name

__all__ = ["TaskStateMixin"]


class TaskStateMixin(NavigatorBase):
    def _slot(self, task: Any) -> TaskSlot:
        if not isinstance(task, RunningTask):
            raise TypeError(
                f"task must be a RunningTask (what goToPose, spin, ... returned), got {type(task).__name__} ({task!r})"
            )
        return self._tasks.route if task is RunningTask.COMPUTE_AND_TRACK_ROUTE else self._tasks.main

    def cancelTask(self) -> None:
        """Cancel the running tasks (the main one and a tracked route); their results then read CANCELED."""
        self.info("Canceling current task.")
        self._tasks.cancel()

    def isTaskComplete(self, task: RunningTask | None = RunningTask.NONE) -> bool:
        """True once the task finished (or none runs). Returns as soon as the result arrives; while the task runs
        it waits at most `timeouts.task_poll` seconds, so polling loops do not spin the CPU."""
        if task is None:
            self.error("Task is None (its goal was rejected): nothing to wait for")
            return True
        slot = self._slot(task)
        done = self._tasks.is_complete(self.timeouts.task_poll, slot)
        if done and slot.result_future is not None:
            if self.getResult() == TaskResult.SUCCEEDED:
                self.debug("Task succeeded!")
            else:
                self.debug(f"Task failed with {self._tasks.status_text()}")
        return done

    def getFeedback(self, task: RunningTask | None = RunningTask.NONE) -> Any:
        """The latest feedback of the main task (None before the first); for COMPUTE_AND_TRACK_ROUTE, the oldest
        route feedback not yet read (None when all were read)."""
        if task is None:
            return None
        slot = self._slot(task)
        if slot is self._tasks.route:
            return slot.pop_feedback()
        return slot.feedback

    def getResult(self) -> TaskResult:
        """SUCCEEDED / CANCELED / FAILED once complete; UNKNOWN while running, after a rejection, or before a task.
        Reports on the task isTaskComplete last saw finish."""
        return self._tasks.task_result()

    def getTaskStatusName(self) -> str:
        """The task's goal status as a word (SUCCEEDED, ABORTED, CANCELED, ... RUNNING, or REJECTED)."""
        slot = self._tasks.reported
        if slot.running() and not self._tasks.is_complete(0.0, slot):
            return "RUNNING"
        return status_name(slot.status)
