"""What the navigator's parts share: the node, its limits, its clients, the task error, and the logging helpers.

Upstream methods here: clearTaskError, setTaskError, getTaskError, info, warn, error, debug (and upstream's
attributes last_action_error_code / last_action_error_msg).
"""

from __future__ import annotations

from typing import Any

from rclpy.node import Node

from tb4.navigator._services import ServiceCaller
from tb4.navigator._task_client import TaskClient, TaskSlot, rejected_code
from tb4.navigator.results import RunningTask
from tb4.navigator.timeouts import NavigatorTimeouts
from tb4.wire import set_supported

__all__ = ["NavigatorBase"]


class NavigatorBase(Node):
    """Base of the navigator mixins (each upstream method group lives in its own module); BasicNavigator builds
    the state."""

    timeouts: NavigatorTimeouts
    _tasks: TaskClient
    _calls: ServiceCaller
    #: status of the last one-shot call (getPath, smoothPath, getRoute...); upstream kept it in `status`,
    #: clobbering the running task's
    last_call_status: int | None = None

    def _ensure_spun(self) -> None:
        """Make sure something spins the node before a wait that needs callbacks (BasicNavigator overrides)."""

    def info(self, msg: str) -> None:
        self.get_logger().info(msg)

    def warn(self, msg: str) -> None:
        self.get_logger().warning(msg)

    def error(self, msg: str) -> None:
        self.get_logger().error(msg)

    def debug(self, msg: str) -> None:
        self.get_logger().debug(msg)

    # --- the task error, shared by tasks and one-shot calls as upstream does -------------------------------------
    def clearTaskError(self) -> None:
        """Forget the last error: getTaskError() reads (0, '') until something fails again."""
        self._tasks.error = (0, "")

    def setTaskError(self, error_code: int, error_msg: str) -> None:
        """Record an error as getTaskError() reports it (upstream's scripts call this for their own failures)."""
        if isinstance(error_code, bool) or not isinstance(error_code, int):
            raise TypeError(f"error_code must be an int, got {type(error_code).__name__}")
        self._tasks.error = (error_code, str(error_msg))

    def getTaskError(self) -> tuple[int, str]:
        """(error_code, error_msg) of the last failed task or call, with Nav2's code; (0, '') after a success."""
        return self._tasks.error

    # Jazzy-era names of the same
    def getLastError(self) -> tuple[int, str]:
        return self.getTaskError()

    def setLastError(self, error_code: int, error_msg: str) -> None:
        self.setTaskError(int(error_code), error_msg)

    def clearLastError(self) -> None:
        self.clearTaskError()

    @property
    def last_action_error_code(self) -> int:
        return self._tasks.error[0]

    @property
    def last_action_error_msg(self) -> str:
        return self._tasks.error[1]

    # --- starting a task -------------------------------------------------------------------------------------------
    def _startTask(
        self, name: str, goal: Any, rejected: str, task: RunningTask, slot: TaskSlot | None = None
    ) -> RunningTask | None:
        """Send `goal` as the running task; `task` if accepted, None (task error: Nav2's UNKNOWN code and
        `rejected`) if the server rejected it."""
        if self._tasks.start(name, goal, slot):
            return task
        code, _ = self._tasks.error
        self.setTaskError(code, rejected)
        self.error(rejected)
        return None

    def _one_shot(self, name: str, goal: Any, action_type: Any, what: str) -> Any:
        """Send a goal, wait for its result (bounded) and return it; a rejection becomes a result carrying the
        action's UNKNOWN code and '`what` was rejected!'. The running tasks are left alone."""
        self.clearTaskError()
        status, result = self._tasks.call(name, goal)
        self.last_call_status = status
        if status is None:
            message = f"{what} was rejected!"
            self.error(message)
            result = action_type.Result()
            # Jazzy's route results have no error_msg: the task error keeps the message for getTaskError()
            set_supported(result, error_code=rejected_code(action_type), error_msg=message)
            self.setTaskError(rejected_code(action_type), message)
        return result
