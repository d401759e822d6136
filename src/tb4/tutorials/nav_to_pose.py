"""Navigate to one pose: from the dock across the warehouse to (-13, 9) facing east."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import close_navigator, finish, open_navigator, start_on_dock, tutorial_arguments

__all__ = ["WORLD", "main", "GOAL"]
WORLD = "warehouse"
GOAL = ((-13.0, 9.0), "EAST")


def main(argv: Sequence[str] | None = None) -> int:
    args = tutorial_arguments(__doc__ or "", argv)
    navigator = open_navigator(args.namespace)
    try:
        from tb4.navigator import TurtleBot4Directions

        start_on_dock(navigator)
        goal_pose = navigator.getPoseStamped(list(GOAL[0]), TurtleBot4Directions[GOAL[1]])
        navigator.startToPose(goal_pose)
        return finish(navigator, "nav_to_pose")
    finally:
        close_navigator(navigator)


if __name__ == "__main__":
    sys.exit(main())
