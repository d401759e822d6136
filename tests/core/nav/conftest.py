"""Shared harness for the nav-core tests: a small map, the real Simulation and a NavigationCore stepped together."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from types import SimpleNamespace

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import load_robot_params
from tb4.nav.params import Nav2Params, load_nav2_params
from tb4.nav.server import NavigationCore
from tb4.nav.tasks import Task
from tb4.sim.simulation import Simulation

PHYSICS_DT = 0.05  # one physics step per control period: fast and still well inside the 20 Hz design
RES = 0.05


def box_map(width: float, height: float, walls: Sequence[tuple[float, float, float, float]] = ()) -> OccupancyMap:
    """A walled rectangle [0, width] x [0, height] with extra wall boxes (x0, y0, x1, y1)."""
    rows, cols = round(height / RES), round(width / RES)
    data = np.zeros((rows, cols), dtype=np.int8)
    data[0, :] = data[-1, :] = 100
    data[:, 0] = data[:, -1] = 100
    for x0, y0, x1, y1 in walls:
        data[round(y0 / RES) : round(y1 / RES), round(x0 / RES) : round(x1 / RES)] = 100
    return OccupancyMap(data, RES, 0.0, 0.0)


class Harness:
    """Simulation + NavigationCore in one fixed-step loop, recording every velocity command sent."""

    def __init__(
        self,
        grid: OccupancyMap,
        start: tuple[float, float, float],
        obstacles: Sequence[object] = (),
        localize: bool = True,
        params: Nav2Params | None = None,
    ) -> None:
        robot_params = load_robot_params(overrides={"lidar": {"beams": 180}})
        self.sim = Simulation(grid, start, start, obstacles=obstacles, params=robot_params, physics_dt=PHYSICS_DT)
        self.commands: list[tuple[float, float, float]] = []
        original = self.sim.set_velocity_command

        def record(v: float, w: float) -> tuple[bool, str]:
            self.commands.append((self.sim.time, v, w))
            return original(v, w)

        self.sim.set_velocity_command = record  # type: ignore[method-assign]
        self.core = NavigationCore(grid, params or load_nav2_params(), self.sim)
        if localize:
            self.core.set_initial_pose(*start)

    def tick(self) -> None:
        self.core.step(self.sim.time)
        self.sim.step(1)

    def run(self, task: Task, max_time: float, until: Callable[[], bool] | None = None) -> Task:
        end = self.sim.time + max_time
        while not task.done and self.sim.time < end:
            self.tick()
            if until is not None and until():
                break
        return task

    def settle(self, seconds: float) -> None:
        for _ in range(round(seconds / PHYSICS_DT)):
            self.tick()

    @property
    def pose(self) -> tuple[float, float, float]:
        p = self.sim.pose()
        return (p.x, p.y, p.yaw)

    def max_command(self) -> tuple[float, float]:
        if not self.commands:
            return (0.0, 0.0)
        arr = np.array(self.commands)
        return (float(np.abs(arr[:, 1]).max()), float(np.abs(arr[:, 2]).max()))


def yaw_error(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


@pytest.fixture
def open_map() -> OccupancyMap:
    return box_map(6.0, 6.0)


@pytest.fixture
def kit() -> SimpleNamespace:
    """The helpers above, for test modules (importing from a conftest is fragile)."""
    return SimpleNamespace(box_map=box_map, Harness=Harness, yaw_error=yaw_error, dt=PHYSICS_DT)
