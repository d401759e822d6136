"""Navigate through six poses around the warehouse in one task, then dock."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import dock_at_the_end, finish, pose_from_table, start_on_dock, tutorial_navigator

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
    with tutorial_navigator(__doc__ or "", argv) as navigator:
        start_on_dock(navigator)
        navigator.startThroughPoses([pose_from_table(navigator, entry) for entry in POSES])
        return dock_at_the_end(navigator, finish(navigator, "nav_through_poses"))


if __name__ == "__main__":
    sys.exit(main())
