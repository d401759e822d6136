"""Upstream import path: `from nav2_simple_commander.robot_navigator import BasicNavigator, RunningTask, TaskResult`."""

from tb4.navigator.basic_navigator import BasicNavigator
from tb4.navigator.results import RunningTask, TaskResult
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts

__all__ = ["BasicNavigator", "RunningTask", "TaskResult", "NavigatorTimeout", "NavigatorTimeouts"]
