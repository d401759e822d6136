"""Upstream import path: `from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult`."""

from tb4.navigator.basic_navigator import BasicNavigator
from tb4.navigator.results import TaskResult
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts

__all__ = ["BasicNavigator", "TaskResult", "NavigatorTimeout", "NavigatorTimeouts"]
