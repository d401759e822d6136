"""Navigate through six poses around the warehouse in one task, then dock."""

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

__all__ = ["WORLD", "main", "POSES"]
WORLD = "warehouse"
POSES = (
    ((-3.0, 0.0), "EAST"),
    ((-3.0, -3.0), "NORTH"),
    ((3.0, -3.0), "NORTH_WEST"),
    ((9.0, -1.0), "WEST"),
    ((9.0, 1.0), "SOUTH"),
    ((-1.0, 1.0), "EAST"),
)


def main(argv: Sequence[str] | None = None) -> int:
    args = tutorial_arguments(__doc__ or "", argv)
    navigator = open_navigator(args.namespace)
    try:
        from tb4.navigator import TurtleBot4Directions

        start_on_dock(navigator)
        goal_poses = [navigator.getPoseStamped(list(xy), TurtleBot4Directions[d]) for xy, d in POSES]
        navigator.startThroughPoses(goal_poses)
        return dock_at_the_end(navigator, finish(navigator, "nav_through_poses"))
    finally:
        close_navigator(navigator)


if __name__ == "__main__":
    sys.exit(main())
