"""A fleet: several robots in one world, stepped together in one fixed-step loop on one clock from one seed.

Each robot is a whole Simulation (drive, Create 3 base, battery, odometry, lidar); the fleet shares the map's
distance field, tells each robot where the others are before it steps (they are moving circles to its lidar and
its collisions, so a robot-robot contact is a bump on both), and says which robot occupies a dock (a dock goal at
a busy dock is refused). Robots step in list order, each seeing the others' current poses.

Determinism: the same world, robot list, seed and calls replay bit-identically. Robot k's noise streams come from
(seed, k) alone, so adding a robot does not change another robot's noise; the first robot's streams are exactly a
single robot's with that seed. Its trajectory can still change when another robot gets in its way.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np

from tb4.sim.collision import DistanceField
from tb4.sim.fleet_spec import RobotSpec, station_obstacle
from tb4.sim.obstacles import static_mask
from tb4.sim.simulation import Simulation
from tb4.sim.world import World

__all__ = ["Fleet", "robot_seed", "robot_nav_seed"]

_FLEET_STREAMS = 0x7B4F1EE7  # spawn-key tag of the fleet's per-robot seed sequences
# Another robot is checked at every physics step when closer than touching + _SENSOR_REACH + _CLOSING: the
# bumper, the IR sensors and wall following's probes (<= 0.5 m) all see it, for a block of steps in which two
# robots at full speed close at most _CLOSING.
_SENSOR_REACH = 0.5
_CLOSING = 0.1


def robot_seed(seed: int, index: int) -> int | np.random.SeedSequence:
    """The seed of robot `index` (0-based): the run's seed for the first robot, an independent stream for the
    others that depends on (seed, index) only."""
    if index == 0:
        return seed
    return np.random.SeedSequence(entropy=seed, spawn_key=(_FLEET_STREAMS, index))


def robot_nav_seed(seed: int, index: int) -> int:
    """The seed of robot `index`'s navigation core (AMCL's particles): the run's seed for the first robot, an
    integer drawn from that robot's own stream for the others."""
    stream = robot_seed(seed, index)
    if isinstance(stream, int):
        return stream
    return int(stream.generate_state(1)[0])


class Fleet:
    """Robots (by namespace, in the world's order) sharing one world; see the module docstring."""

    def __init__(self, world: World, robots: Sequence[RobotSpec], seed: int = 0, **sim_kwargs: Any) -> None:
        if not robots:
            raise ValueError("a fleet needs at least one robot")
        names = [r.namespace for r in robots]
        if len(set(names)) != len(names):
            raise ValueError(f"robot namespaces must be unique, got {names}")
        self.world = world
        docks = world.all_docks
        # stations of the docks after the first, which the map does not draw
        self.obstacles = (*world.obstacles, *(station_obstacle(d) for d in docks[1:]))
        mask = static_mask(world.map, [o for o in self.obstacles if not o.moving])
        field = DistanceField.from_mask(world.map, mask)
        self.robots: dict[str, Simulation] = {}
        for i, spec in enumerate(robots):
            sim = Simulation(
                world.map,
                spec.dock,
                spec.start,
                obstacles=self.obstacles,
                seed=robot_seed(seed, i),
                cliffs=getattr(world, "cliffs", ()),
                docks=docks,
                distance_field=field,
                **sim_kwargs,
            )
            sim.dock_occupant = self._occupant_for(spec.namespace)
            sim.fleet_size = len(robots)
            self.robots[spec.namespace] = sim
        self._sims = list(self.robots.items())
        self._radius = {name: sim.params.drive.radius for name, sim in self._sims}
        self._order = {name: k for k, (name, _) in enumerate(self._sims)}
        # physics steps two robots need at full speed to close _CLOSING (the drive limit of any robot)
        speed = max(sim.params.drive.max_linear_speed for sim in self)
        self._block = max(1, int(_CLOSING / (2.0 * speed * self.physics_dt)))
        self._update_peers()

    # ------------------------------------------------------------------ clock and stepping
    @property
    def time(self) -> float:
        return self._sims[0][1].time

    @property
    def steps(self) -> int:
        return self._sims[0][1].steps

    @property
    def physics_dt(self) -> float:
        return self._sims[0][1].physics_dt

    def step(self, n: int = 1) -> None:
        """Advance every robot n physics steps; each robot steps knowing the poses of the others at that moment.

        Only robots that the bumper or the short-range sensors could meet within a block of steps are checked
        during it; the others are too far to matter, and every reading between steps (scans, dock checks) sees
        all of them again."""
        sims = self._sims
        radius = self._radius
        remaining = int(n)
        while remaining > 0:
            block = min(remaining, self._block)
            near = self._near_pairs()
            for _ in range(block):
                for name, sim in sims:
                    others = near[name]
                    sim.peers = [(o.x, o.y, radius[other]) for other, o in others] if others else []
                    sim.step(1)
            remaining -= block
        self._update_peers()

    def _near_pairs(self) -> dict[str, list[tuple[str, Simulation]]]:
        """For each robot, the others within touching distance plus _SENSOR_REACH + _CLOSING."""
        near: dict[str, list[tuple[str, Simulation]]] = {name: [] for name, _ in self._sims}
        sims, radius = self._sims, self._radius
        for i, (a, sa) in enumerate(sims):
            for b, sb in sims[i + 1 :]:
                if math.hypot(sa.x - sb.x, sa.y - sb.y) < radius[a] + radius[b] + _SENSOR_REACH + _CLOSING:
                    near[a].append((b, sb))
                    near[b].append((a, sa))
        for others in near.values():  # keep the fleet's order, so each robot's circle list is in robot order
            others.sort(key=lambda item: self._order[item[0]])
        return near

    def _update_peers(self) -> None:
        """Peers as of now for every robot (readings between steps: scans, clearance, dock checks)."""
        for name, sim in self._sims:
            sim.peers = [(o.x, o.y, self._radius[other]) for other, o in self._sims if other != name]

    # ------------------------------------------------------------------ robots and docks
    def __getitem__(self, namespace: str) -> Simulation:
        try:
            return self.robots[namespace]
        except KeyError:
            raise KeyError(f"no robot {namespace!r} in this fleet (robots: {', '.join(self.robots)})") from None

    def __iter__(self) -> Iterator[Simulation]:
        return iter(self.robots.values())

    def __len__(self) -> int:
        return len(self.robots)

    @property
    def namespaces(self) -> list[str]:
        return list(self.robots)

    def occupant(self, dock: tuple[float, float, float], exclude: str = "") -> str:
        """The robot on or next to a dock pose (within a robot's diameter), '' if the dock is free."""
        for name, sim in self._sims:
            if name != exclude and math.hypot(sim.x - dock[0], sim.y - dock[1]) < 2.0 * self._radius[name]:
                return name
        return ""

    def _occupant_for(self, namespace: str) -> Any:
        return lambda dock: self.occupant(dock, exclude=namespace)
