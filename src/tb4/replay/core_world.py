"""The world a simulator serves, without ROS: its robots' Simulations (or a Fleet) and their navigation cores,
built from the simulator's settings. A live `tb4 sim` and `tb4 replay` build it here, the same way, so a replay
starts from exactly the world the run started from."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tb4.nav.server import NavigationCore
from tb4.sim.fleet import Fleet, robot_nav_seed
from tb4.sim.fleet_spec import RobotSpec, robots_on_docks
from tb4.sim.simulation import Simulation
from tb4.sim.world import World

__all__ = ["CoreSettings", "CoreWorld", "build_core_world", "fleet_specs"]


@dataclass(frozen=True)
class CoreSettings:
    """What decides the world a run starts from (the simulator's options that are not about serving it)."""

    seed: int = 0
    robots: int = 0  # N > 0: a fleet robot1..robotN on the world's first N docks (0: the world's robots, or one)
    namespace: str = ""
    battery: float | None = None
    physics_dt: float = 0.01
    exact: bool = False
    localization: str = "amcl"

    def to_json(self) -> dict[str, Any]:
        return {
            "seed": self.seed,
            "robots": self.robots,
            "namespace": self.namespace,
            "battery": self.battery,
            "physics_dt": self.physics_dt,
            "exact": self.exact,
            "localization": self.localization,
        }


@dataclass
class CoreWorld:
    """The built world: every robot's Simulation and nav core in order; `fleet` when several share the world."""

    world: World
    sims: list[Simulation]
    navs: list[NavigationCore]
    fleet: Fleet | None
    specs: tuple[RobotSpec, ...]


def fleet_specs(world: World, settings: CoreSettings) -> tuple[RobotSpec, ...]:
    """The fleet to build: --robots N on the first N docks, else the robots the world lists (none: one robot).

    Raises:
        ValueError: a namespace and a fleet both asked for.
    """
    if settings.robots and settings.namespace:
        raise ValueError("give --namespace (one robot) or --robots N (robot1..robotN), not both")
    if settings.robots:
        return robots_on_docks(world.all_docks, settings.robots, f"world {world.name!r}")
    if world.robots and settings.namespace:
        raise ValueError(f"world {world.name!r} lists its robots and their namespaces; drop --namespace")
    return world.robots


def build_core_world(world: World, settings: CoreSettings) -> CoreWorld:
    """Build the robots and their navigation cores of `world` as `settings` say.

    Args:
        world: the loaded world.
        settings: seed, robots, battery, step, noise and localization.

    Returns:
        The world, ready to step.

    Raises:
        ValueError: a battery level outside [0, 1], or a fleet that does not fit the world.
    """
    kwargs: dict[str, Any] = {"seed": settings.seed, "physics_dt": settings.physics_dt}
    if settings.battery is not None:
        if not (0.0 <= settings.battery <= 1.0):
            raise ValueError(f"battery must be between 0 and 1, got {settings.battery}")
        kwargs["battery_level"] = settings.battery
    noisy = not settings.exact
    specs = fleet_specs(world, settings)
    if specs:
        fleet = Fleet(world, specs, odom_noise=noisy, lidar_noise=noisy, **kwargs)
        sims = list(fleet)
        navs = [
            NavigationCore(
                world.map, robot=sim, localization=settings.localization, seed=robot_nav_seed(settings.seed, k)
            )
            for k, sim in enumerate(sims)
        ]
        return CoreWorld(world, sims, navs, fleet, specs)
    sim = Simulation.from_world(world, odom_noise=noisy, lidar_noise=noisy, **kwargs)
    nav = NavigationCore(world.map, robot=sim, localization=settings.localization, seed=settings.seed)
    return CoreWorld(world, [sim], [nav], None, ())
