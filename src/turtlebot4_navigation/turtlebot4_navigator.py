"""Upstream import path:
`from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator`."""

from tb4.core.directions import TurtleBot4Directions
from tb4.navigator.results import RunningTask, TaskResult
from tb4.navigator.turtlebot4_navigator import TurtleBot4Navigator

__all__ = ["TurtleBot4Directions", "TurtleBot4Navigator", "RunningTask", "TaskResult"]
