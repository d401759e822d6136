"""Follow four waypoints around the depot (the waypoint follower pauses at each), then dock."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import dock_at_the_end, finish, pose_from_table, start_on_dock, tutorial_navigator

__all__ = ["WORLD", "main", "WAYPOINTS"]
WORLD = "depot"
WAYPOINTS = (
    ((-3.3, 5.9), "NORTH"),
    ((2.1, 6.3), "EAST"),
    ((2.0, 1.0), "SOUTH"),
    ((-1.0, 0.0), "NORTH"),
)


def main(argv: Sequence[str] | None = None) -> int:
    with tutorial_navigator(__doc__ or "", argv) as navigator:
        start_on_dock(navigator)
        navigator.startFollowWaypoints([pose_from_table(navigator, entry) for entry in WAYPOINTS])
        return dock_at_the_end(navigator, finish(navigator, "follow_waypoints"))


if __name__ == "__main__":
    sys.exit(main())
