"""Fleet delivery: three robots (/robot1../robot3, one TurtleBot4Navigator each) share six deliveries in the
warehouse, then go back to their docks to charge.

The coordination rules, all decided here by the mission (the robots only navigate):
- each delivery goes to the nearest free robot (straight line from where that robot last stopped);
- no two robots drive to goals closer than SPACING to each other, so they never meet head-on at a drop-off; a
  delivery too close to a busy robot's goal waits until that robot has arrived (when every robot is free,
  nothing waits, so the mission cannot deadlock);
- the dock area is one lane: robots undock, and later dock to charge, one at a time (a charging turn each).

Run with `tb4 run fleet_delivery` (which starts `tb4 sim --robots 3`); against a running fleet, give
`--namespaces /robot1,/robot2,/robot3`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from tb4.tutorials.common import close_navigator, open_navigator

__all__ = ["WORLD", "ROBOTS", "DELIVERIES", "SPACING", "Courier", "assign", "main"]

WORLD = "warehouse"
ROBOTS = 3
SPACING = 2.5  # m: the closest two robots' goals may be at once
DELIVERIES: tuple[tuple[str, tuple[float, float], str], ...] = (
    ("west shelf", (-5.0, 1.0), "WEST"),
    ("east bay", (5.0, 4.0), "EAST"),
    ("south-west corner", (-4.0, -5.0), "SOUTH"),
    ("north-east post", (-1.0, 6.0), "WEST"),
    ("south-east bay", (3.0, -6.0), "EAST"),
    ("north-west post", (-6.0, 4.0), "NORTH"),
)
STAGING_BACK = 1.0  # m behind its dock where a robot lines up to dock
TASK_TIMEOUT = 600.0  # s of wall time for one delivery before the mission gives up


@dataclass
class Courier:
    """One robot of the fleet: its navigator, its dock, where it rests now, and what it is doing."""

    namespace: str
    navigator: Any
    dock: tuple[float, float, float]
    at: tuple[float, float]
    job: tuple[str, tuple[float, float], str] | None = None
    started: float = 0.0
    delivered: list[str] = field(default_factory=list)


def assign(
    pending: Sequence[tuple[str, tuple[float, float], str]], couriers: Sequence[Courier]
) -> list[tuple[Courier, tuple[str, tuple[float, float], str]]]:
    """Pairs (courier, delivery) to start now: in delivery order, the nearest free courier takes a delivery whose
    place keeps SPACING from every busy robot's goal. Pure, so it is tested without ROS."""
    free = [c for c in couriers if c.job is None]
    taken: list[tuple[float, float]] = [c.job[1] for c in couriers if c.job is not None]
    out = []
    for delivery in pending:
        if not free:
            break
        place = delivery[1]
        nearest = min(free, key=lambda c: (math.dist(c.at, place), c.namespace))
        if any(math.dist(place, goal) < SPACING for goal in taken):
            continue  # too close to where another robot is driving: it waits
        out.append((nearest, delivery))
        free.remove(nearest)
        taken.append(place)
    return out


def _arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--namespaces", default=",".join(f"/robot{k + 1}" for k in range(ROBOTS)), help="the fleet's namespaces"
    )
    return parser.parse_known_args(argv)[0]


def _docks(count: int) -> list[tuple[float, float, float]]:
    """The first `count` docks of the world the simulator serves (TB4_WORLD, set by tb4 run)."""
    from tb4.sim.world import load_world

    world = load_world(os.environ.get("TB4_WORLD", WORLD))
    docks = world.all_docks
    if len(docks) < count:
        raise SystemExit(f"fleet_delivery: world {world.name!r} has {len(docks)} dock(s), {count} robots need {count}")
    return list(docks[:count])


def main(argv: Sequence[str] | None = None) -> int:
    from tb4.navigator.timeouts import NavigatorTimeouts

    args = _arguments(argv)
    namespaces = [ns.strip() for ns in args.namespaces.split(",") if ns.strip()]
    # one simulator process answers for every robot: on a loaded machine its services answer later than one
    # robot's do, so discovery and answers get three times the default limits
    timeouts = NavigatorTimeouts(server=30.0, response=30.0)
    couriers: list[Courier] = []
    try:
        for ns, dock in zip(namespaces, _docks(len(namespaces)), strict=True):
            couriers.append(Courier(ns, open_navigator(ns, timeouts), dock, (dock[0], dock[1])))
        return _mission(couriers)
    except KeyboardInterrupt:
        for c in couriers:
            c.navigator.cancelTask()
        return 130
    finally:
        for c in couriers:
            close_navigator(c.navigator)


def _mission(couriers: list[Courier]) -> int:
    from tb4.navigator import TaskResult, TurtleBot4Directions

    for c in couriers:  # the dock lane, one robot at a time
        nav = c.navigator
        nav.setInitialPose(nav.getPoseStamped(c.at, TurtleBot4Directions.NORTH))
        nav.waitUntilNav2Active()
        nav.undock()
        nav.info(f"{c.namespace} undocked")
    pending = list(DELIVERIES)
    failed: list[str] = []
    while pending or any(c.job is not None for c in couriers):
        for courier, delivery in assign(pending, couriers):
            pending.remove(delivery)
            name, (x, y), heading = delivery
            nav = courier.navigator
            nav.info(f"{courier.namespace} takes the delivery to {name}")
            nav.goToPose(nav.getPoseStamped([x, y], TurtleBot4Directions[heading]))
            courier.job, courier.started = delivery, time.monotonic()
        for c in couriers:
            if c.job is None:
                continue
            if not c.navigator.isTaskComplete() and time.monotonic() - c.started < TASK_TIMEOUT:
                continue
            if c.navigator.getResult() == TaskResult.SUCCEEDED:
                c.navigator.info(f"{c.namespace} delivered to {c.job[0]}")
                c.delivered.append(c.job[0])
                c.at = c.job[1]
            else:
                c.navigator.cancelTask()
                c.navigator.error(f"{c.namespace} could not deliver to {c.job[0]}")
                failed.append(c.job[0])
            c.job = None
        time.sleep(0.05)
    docked = [_charge(c) for c in couriers]  # charging turns: one robot in the dock lane at a time
    for c in couriers:
        c.navigator.info(f"{c.namespace}: {len(c.delivered)} deliveries ({', '.join(c.delivered) or 'none'})")
    if failed or not all(docked):
        couriers[0].navigator.error(f"fleet delivery incomplete: failed {failed}, docked {docked}")
        return 1
    couriers[0].navigator.info(f"all {len(DELIVERIES)} deliveries made; every robot is charging")
    return 0


def _charge(courier: Courier) -> bool:
    """Line up behind this robot's dock and dock (the dock refuses if another robot is on it)."""
    from tb4.navigator import TurtleBot4Directions

    nav = courier.navigator
    x, y, yaw = courier.dock
    staging = (x - STAGING_BACK * math.cos(yaw), y - STAGING_BACK * math.sin(yaw))
    nav.startToPose(nav.getPoseStamped(list(staging), TurtleBot4Directions.NORTH))
    nav.dock()
    if not nav.getDockedStatus():
        nav.error(f"{courier.namespace} failed to dock")
        return False
    nav.info(f"{courier.namespace} docked and charging")
    return True


if __name__ == "__main__":
    sys.exit(main())
