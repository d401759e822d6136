"""What the navigator's parts share: the node, its limits, its clients, and upstream's logging helpers."""

from __future__ import annotations

from rclpy.node import Node

from tb4.navigator._services import ServiceCaller
from tb4.navigator._task_client import TaskClient
from tb4.navigator.timeouts import NavigatorTimeouts

__all__ = ["NavigatorBase"]


class NavigatorBase(Node):
    """Base of the navigator mixins (each concern lives in its own module); BasicNavigator builds the state."""

    timeouts: NavigatorTimeouts
    _tasks: TaskClient
    _calls: ServiceCaller

    def info(self, msg: str) -> None:
        self.get_logger().info(msg)

    def warn(self, msg: str) -> None:
        self.get_logger().warning(msg)

    def error(self, msg: str) -> None:
        self.get_logger().error(msg)

    def debug(self, msg: str) -> None:
        self.get_logger().debug(msg)

    # --- the last error, shared by tasks and one-shot calls as upstream does ------------------------------------
    def getTaskError(self) -> tuple[int, str]:
        """(error_code, error_msg) of the last failed task or call; (0, '') after a success."""
        return self._tasks.error

    def getLastError(self) -> tuple[int, str]:
        """Older name of getTaskError."""
        return self.getTaskError()

    def setLastError(self, error_code: int, error_msg: str) -> None:
        self._tasks.error = (int(error_code), str(error_msg))

    def clearLastError(self) -> None:
        self._tasks.error = (0, "")
