"""Navigate to one pose: from the dock across the warehouse to (-13, 9) facing east."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import finish, pose_from_table, start_on_dock, tutorial_navigator

__all__ = ["WORLD", "main", "GOAL"]
WORLD = "warehouse"
GOAL = ((-13.0, 9.0), "EAST")


def main(argv: Sequence[str] | None = None) -> int:
    with tutorial_navigator(__doc__ or "", argv) as navigator:
        start_on_dock(navigator)
        navigator.startToPose(pose_from_table(navigator, GOAL))
        return finish(navigator, "nav_to_pose")


if __name__ == "__main__":
    sys.exit(main())
