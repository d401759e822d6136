"""What every tutorial does first (upstream's preamble), and how it ends."""

from __future__ import annotations

import argparse
import contextlib
import time
from collections.abc import Iterator, Sequence
from typing import Any

from tb4.rosenv import apply_safe_ros_defaults, require_ros

__all__ = [
    "tutorial_arguments",
    "tutorial_navigator",
    "open_navigator",
    "pose_from_table",
    "start_on_dock",
    "finish",
    "close_navigator",
    "dock_at_the_end",
    "sim_sleep",
]


def tutorial_arguments(description: str, argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--namespace", default="", help="robot namespace, e.g. robot1")
    return parser.parse_known_args(argv)[0]


def open_navigator(namespace: str = "", timeouts: Any = None) -> Any:
    """rclpy.init + a TurtleBot4Navigator (the same objects an upstream script creates); `timeouts`: a
    tb4.navigator NavigatorTimeouts (None: the defaults)."""
    apply_safe_ros_defaults()
    require_ros()
    import rclpy

    from tb4.navigator import TurtleBot4Navigator

    if not rclpy.ok():
        rclpy.init()
    return TurtleBot4Navigator(namespace=namespace, timeouts=timeouts)


@contextlib.contextmanager
def tutorial_navigator(description: str, argv: Sequence[str] | None) -> Iterator[Any]:
    """The tutorial's navigator (in the --namespace given), destroyed with rclpy shut down however main() ends."""
    args = tutorial_arguments(description, argv)
    navigator = open_navigator(args.namespace)
    try:
        yield navigator
    finally:
        close_navigator(navigator)


def pose_from_table(navigator: Any, entry: tuple[tuple[float, float], str]) -> Any:
    """A PoseStamped from a tutorial's table entry ((x, y), "DIRECTION"), as upstream writes its poses."""
    from tb4.navigator import TurtleBot4Directions

    (x, y), direction = entry
    return navigator.getPoseStamped([x, y], TurtleBot4Directions[direction])


def start_on_dock(navigator: Any, clear_costmaps: bool = False) -> None:
    """Upstream's preamble: dock if needed, initial pose at the dock facing north, wait for Nav2, undock.
    create_path's version clears the costmaps before the initial pose."""
    from tb4.navigator import TurtleBot4Directions

    if not navigator.getDockedStatus():
        navigator.info("Docking before initialising pose")
        navigator.dock()
    if clear_costmaps:
        navigator.clearAllCostmaps()
    initial_pose = navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH)
    navigator.setInitialPose(initial_pose)
    navigator.waitUntilNav2Active()
    navigator.undock()


def finish(navigator: Any, what: str) -> int:
    """Exit status from the last task: 0 when it succeeded, 1 with a logged reason otherwise."""
    from tb4.navigator import TaskResult

    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        return 0
    code, message = navigator.getTaskError()
    navigator.error(f"{what} did not succeed: {result.name} (error {code}: {message or 'no message'})")
    return 1


def dock_at_the_end(navigator: Any, status: int) -> int:
    """Dock as the tutorial's last step; a failed dock turns success into failure (with upstream's message)."""
    navigator.dock()
    if not navigator.getDockedStatus():
        navigator.error("Robot failed to dock")
        return 1
    return status


def close_navigator(navigator: Any) -> None:
    import rclpy

    navigator.destroyNode()
    rclpy.try_shutdown()


def sim_sleep(navigator: Any, seconds: float, stall_timeout: float = 10.0) -> None:
    """Sleep `seconds` of the navigator's clock (sim time under the simulator), failing if time stops."""
    clock = navigator.get_clock()
    start = clock.now().nanoseconds
    last_value, last_change = start, time.monotonic()
    while (now := clock.now().nanoseconds) - start < seconds * 1e9:
        if now != last_value:
            last_value, last_change = now, time.monotonic()
        elif time.monotonic() - last_change > stall_timeout:
            raise TimeoutError(f"the clock stopped for {stall_timeout:g} s: is the simulator still running?")
        time.sleep(0.002)
