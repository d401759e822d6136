"""TurtleBot 4 Navigator: script and test TurtleBot 4 missions, with a built-in simulator.

    from tb4 import TurtleBot4Navigator, TurtleBot4Directions, TaskResult

Importing `tb4` itself never imports rclpy and never changes os.environ; the navigator classes load (with ROS)
on first use. The safe DDS defaults (apply_safe_ros_defaults) are applied by what starts nodes: the `tb4`
command, the tutorials, and the navigator package (tb4.navigator, the upstream import paths), which user scripts
import before rclpy.init reads the environment.
"""

from typing import Any

from tb4.rosenv import apply_safe_ros_defaults

__version__ = "0.1.0"
_NAVIGATOR_NAMES = ("BasicNavigator", "TaskResult", "TurtleBot4Navigator", "TurtleBot4Directions", "NavigatorTimeouts")
__all__ = ["__version__", "apply_safe_ros_defaults", *_NAVIGATOR_NAMES]


def __getattr__(name: str) -> Any:
    if name in _NAVIGATOR_NAMES:
        import tb4.navigator

        return getattr(tb4.navigator, name)
    raise AttributeError(f"module 'tb4' has no attribute {name!r}")
