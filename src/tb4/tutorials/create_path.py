"""Create a path from poses given with RViz's "2D Pose Estimate" (or `tb4 pose X Y HEADING`), then follow it.

Each pose published on `initialpose` is one waypoint; press Enter to finish the path.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import close_navigator, dock_at_the_end, finish, open_navigator, tutorial_arguments

__all__ = ["WORLD", "main"]
WORLD = "warehouse"


def main(argv: Sequence[str] | None = None) -> int:
    args = tutorial_arguments(__doc__ or "", argv)
    navigator = open_navigator(args.namespace)
    try:
        from tb4.navigator import TurtleBot4Directions

        goal_poses = navigator.createPath()
        if len(goal_poses) == 0:
            navigator.error("No poses were given, exiting.")
            return 0
        if not navigator.getDockedStatus():
            navigator.info("Docking before initialising pose")
            navigator.dock()
        navigator.clearAllCostmaps()
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startFollowWaypoints(goal_poses)
        return dock_at_the_end(navigator, finish(navigator, "create_path"))
    finally:
        close_navigator(navigator)


if __name__ == "__main__":
    sys.exit(main())
