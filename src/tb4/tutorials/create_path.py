"""Create a path from poses given with RViz's "2D Pose Estimate" (or `tb4 pose X Y HEADING`), then follow it.

Each pose published on `initialpose` is one waypoint; press Enter to finish the path.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import dock_at_the_end, finish, start_on_dock, tutorial_navigator

__all__ = ["WORLD", "main"]
WORLD = "warehouse"


def main(argv: Sequence[str] | None = None) -> int:
    with tutorial_navigator(__doc__ or "", argv) as navigator:
        goal_poses = navigator.createPath()
        if len(goal_poses) == 0:
            navigator.error("No poses were given, exiting.")
            return 0
        start_on_dock(navigator, clear_costmaps=True)
        navigator.startFollowWaypoints(goal_poses)
        return dock_at_the_end(navigator, finish(navigator, "create_path"))


if __name__ == "__main__":
    sys.exit(main())
