"""The user's API: BasicNavigator (Nav2 Simple Commander) and TurtleBot4Navigator, plus Nav2's Python helpers.

    from tb4.navigator import TurtleBot4Navigator, TurtleBot4Directions, TaskResult, RunningTask

Every wait is bounded (see NavigatorTimeouts); a timeout raises NavigatorTimeout naming what was missing.
Importing this package needs the ROS 2 wheels (rclpy) and our interface packages.
"""

from tb4.core.directions import TurtleBot4Directions
from tb4.navigator.basic_navigator import BasicNavigator
from tb4.navigator.costmap_2d import PyCostmap2D
from tb4.navigator.footprint_collision_checker import FootprintCollisionChecker
from tb4.navigator.line_iterator import LineIterator
from tb4.navigator.results import RunningTask, TaskResult
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts
from tb4.navigator.turtlebot4_navigator import TurtleBot4Navigator

__all__ = [
    "BasicNavigator",
    "TaskResult",
    "RunningTask",
    "TurtleBot4Navigator",
    "TurtleBot4Directions",
    "PyCostmap2D",
    "FootprintCollisionChecker",
    "LineIterator",
    "NavigatorTimeouts",
    "NavigatorTimeout",
]
