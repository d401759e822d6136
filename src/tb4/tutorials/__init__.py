"""The TurtleBot 4 tutorials as our own programs, with upstream's behaviour and messages.

Each module has `WORLD` (the world it runs in), `SUMMARY` (one line) and `main(argv) -> int` (0 on success, 1
with a logged reason on failure). Run one with `tb4 run NAME`, or `python -m tb4.tutorials.NAME` against a
simulator (or robot) that is already running.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType

__all__ = ["Tutorial", "TUTORIALS", "get_tutorial"]


@dataclass(frozen=True)
class Tutorial:
    name: str
    world: str
    summary: str
    interactive: bool = False
    robots: int = 0  # a fleet tutorial: tb4 run starts `tb4 sim --robots N` (robot1..robotN)

    def module(self) -> ModuleType:
        return importlib.import_module(f"tb4.tutorials.{self.name}")


TUTORIALS: dict[str, Tutorial] = {
    t.name: t
    for t in (
        Tutorial("nav_to_pose", "warehouse", "undock, drive across the warehouse to (-13, 9) facing east"),
        Tutorial("nav_through_poses", "warehouse", "drive through six poses around the warehouse, then dock"),
        Tutorial("follow_waypoints", "depot", "follow four waypoints around the depot, then dock"),
        Tutorial(
            "create_path", "warehouse", "collect poses from 'initialpose' (RViz 2D Pose Estimate / tb4 pose)", True
        ),
        Tutorial("mail_delivery", "warehouse", "menu-driven deliveries to five places in the warehouse", True),
        Tutorial("patrol_loop", "warehouse", "patrol four poses, docking to charge when the battery runs low"),
        Tutorial("natural_language_nav", "depot", "drive by typed commands through a language model, safely"),
        Tutorial(
            "fleet_delivery",
            "warehouse",
            "three robots share six deliveries (nearest free robot, kept apart), then take turns to dock",
            robots=3,
        ),
        Tutorial("bump_and_go", "depot", "Create 3 API only: drive until a bump, back off, turn away; three bumps"),
    )
}


def get_tutorial(name: str) -> Tutorial:
    try:
        return TUTORIALS[name]
    except KeyError:
        import difflib

        close = difflib.get_close_matches(name, TUTORIALS, n=1)
        hint = f"; did you mean '{close[0]}'?" if close else ""
        raise KeyError(f"unknown tutorial '{name}'{hint} (tb4 run --list shows them)") from None
