"""Follow four waypoints around the depot (the waypoint follower pauses at each), then dock."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import (
    close_navigator,
    dock_at_the_end,
    finish,
    open_navigator,
    start_on_dock,
    tutorial_arguments,
)

__all__ = ["WORLD", "main", "WAYPOINTS"]
WORLD = "depot"
WAYPOINTS = (
    ((-3.3, 5.9), "NORTH"),
    ((2.1, 6.3), "EAST"),
    ((2.0, 1.0), "SOUTH"),
    ((-1.0, 0.0), "NORTH"),
)


def main(argv: Sequence[str] | None = None) -> int:
    args = tutorial_arguments(__doc__ or "", argv)
    navigator = open_navigator(args.namespace)
    try:
        from tb4.navigator import TurtleBot4Directions

        start_on_dock(navigator)
        goal_poses = [navigator.getPoseStamped(list(xy), TurtleBot4Directions[d]) for xy, d in WAYPOINTS]
        navigator.startFollowWaypoints(goal_poses)
        return dock_at_the_end(navigator, finish(navigator, "follow_waypoints"))
    finally:
        close_navigator(navigator)


if __name__ == "__main__":
    sys.exit(main())
