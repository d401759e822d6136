"""Mail delivery: pick a destination from a menu, the robot drives there; repeat until Exit (or end of input)."""

from __future__ import annotations

import sys
from collections.abc import Sequence

from tb4.tutorials.common import pose_from_table, start_on_dock, tutorial_navigator

__all__ = ["WORLD", "main", "DESTINATIONS", "menu_text"]
WORLD = "warehouse"
DESTINATIONS = (
    ("Home", (-1.0, 1.0), "EAST"),
    ("Position 1", (10.0, 6.0), "EAST"),
    ("Position 2", (-9.0, 9.0), "NORTH"),
    ("Position 3", (-12.0, 2.0), "NORTH_WEST"),
    ("Position 4", (3.0, -7.0), "WEST"),
    ("Exit", None, None),
)


def menu_text() -> str:
    lines = ["Please enter the number corresponding to the desired robot goal position:"]
    lines += [f"    {i}. {name}" for i, (name, _, _) in enumerate(DESTINATIONS)]
    return "\n".join(lines) + "\nSelection: "


def main(argv: Sequence[str] | None = None) -> int:
    failures = 0
    with tutorial_navigator(__doc__ or "", argv) as navigator:
        from tb4.navigator import TaskResult

        start_on_dock(navigator)
        while True:
            try:
                raw = input(menu_text())
            except EOFError:
                print()
                navigator.info("End of input: exiting.")
                break
            try:
                selected = int(raw)
            except ValueError:
                navigator.error(f"Invalid goal selection: {raw}")
                continue
            if not 0 <= selected < len(DESTINATIONS):
                navigator.error(f"Goal selection out of bounds: {selected}")
                continue
            name, position, direction = DESTINATIONS[selected]
            if position is None or direction is None:  # Exit
                break
            navigator.startToPose(pose_from_table(navigator, (position, direction)))
            if navigator.getResult() != TaskResult.SUCCEEDED:
                failures += 1
        return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
