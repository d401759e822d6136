"""The user's API: BasicNavigator (Nav2 Simple Commander) and TurtleBot4Navigator, plus Nav2's Python helpers.

    from tb4.navigator import TurtleBot4Navigator, TurtleBot4Directions, TaskResult, RunningTask

Every wait is bounded (see NavigatorTimeouts); a timeout raises NavigatorTimeout naming what was missing.
Importing this package needs the ROS 2 wheels (rclpy) and our interface packages. It is the entry point of user
scripts, which call rclpy.init themselves after importing it, so it applies the safe DDS defaults
(tb4.rosenv.apply_safe_ros_defaults: loopback discovery unless the user chose, and there DDS data over loopback UDP)
before anything reads them.
"""

from tb4.rosenv import apply_safe_ros_defaults

apply_safe_ros_defaults()

# The imports below come after the defaults on purpose: rclpy may read the environment as it loads.

from tb4.core.directions import TurtleBot4Directions  # noqa: E402
from tb4.navigator.basic_navigator import BasicNavigator  # noqa: E402
from tb4.navigator.costmap_2d import PyCostmap2D  # noqa: E402
from tb4.navigator.footprint_collision_checker import FootprintCollisionChecker  # noqa: E402
from tb4.navigator.line_iterator import LineIterator  # noqa: E402
from tb4.navigator.results import RunningTask, TaskResult  # noqa: E402
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts  # noqa: E402
from tb4.navigator.turtlebot4_navigator import TurtleBot4Navigator  # noqa: E402

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
