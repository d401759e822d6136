"""Distance field, swept collision (no tunnelling), circles and static obstacle rasterization."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tb4.core.geometry import arc_pose
from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import default_robot_params
from tb4.sim.collision import CollisionChecker, DistanceField, circles_clearance
from tb4.sim.obstacles import Obstacle, static_mask
from tb4.sim.simulation import Simulation

pytestmark = pytest.mark.core

RES = 0.03
R = 0.175


def wall_map(wall_col: int = 100, thickness: int = 1) -> OccupancyMap:
    """6 x 6 m free square (origin at 0, 0) with a vertical wall `thickness` cells thick at column wall_col."""
    data = np.zeros((200, 200), dtype=np.int8)
    data[:, wall_col : wall_col + thickness] = 100
    return OccupancyMap(data, RES, 0.0, 0.0)


def checker(grid: OccupancyMap) -> CollisionChecker:
    p = default_robot_params().drive
    return CollisionChecker(DistanceField.from_mask(grid), p.radius, p.collision_min_step)


def test_field_is_metric_distance_between_cell_centres() -> None:
    grid = wall_map()
    f = DistanceField.from_mask(grid)
    inner = f.dist[f.pad : -f.pad, f.pad : -f.pad]
    assert inner[50, 100] == 0.0
    assert inner[50, 90] == pytest.approx(10 * RES)
    assert inner[50, 101] == pytest.approx(RES)


def test_clearance_is_distance_to_the_wall_face() -> None:
    f = DistanceField.from_mask(wall_map())
    face = 100 * RES  # left face of the wall
    for x in (1.6, 2.0, 2.5, 2.9, 2.95):  # nearer the wall than the map edge
        assert f.clearance(x, 3.0) == pytest.approx(face - x, abs=1e-9)
    assert f.clearance(face + 0.5 * RES, 3.0) < 0.0  # inside the wall


def test_off_map_counts_as_occupied() -> None:
    f = DistanceField.from_mask(wall_map())
    assert f.clearance(-1.0, 3.0) < 0.0
    assert f.clearance(100.0, 3.0) < 0.0
    assert f.clearance(0.3, 3.0) == pytest.approx(0.3, abs=1e-9)  # the map edge is a wall


def test_free_motion_is_the_exact_arc() -> None:
    c = checker(wall_map())
    assert c.move(1.0, 1.5, 0.2, 0.31, 1.0, 0.5) == (*arc_pose(1.0, 1.5, 0.2, 0.31, 1.0, 0.5), False)
    assert c.move(1.0, 1.5, 0.2, 0.0, 1.9, 0.5) == (1.0, 1.5, pytest.approx(0.2 + 0.95), False)


@pytest.mark.parametrize("dt", [0.01, 0.1, 0.5, 1.0])
@pytest.mark.parametrize("start_x", [1.0, 2.3, 2.5, 2.7])
def test_never_tunnels_through_a_one_cell_wall(dt: float, start_x: float) -> None:
    c = checker(wall_map(thickness=1))
    x, y, yaw = start_x, 3.0, 0.0
    blocked = False
    for _ in range(int(8.0 / dt)):
        x, y, yaw, blocked = c.move(x, y, yaw, 0.31, 0.0, dt)
        assert x < 3.0
        if blocked:
            break
    assert blocked
    wall = 3.0
    assert wall - R - c.min_step - 1e-9 <= x <= wall - R + 1e-9  # stopped just short of touching


def test_stopping_at_an_angle_keeps_the_last_free_pose() -> None:
    c = checker(wall_map())
    x, y, yaw, blocked = c.move(2.4, 3.0, 0.5, 0.31, 0.0, 10.0)
    assert blocked
    assert c.field.clearance(x, y) >= R
    assert (y - 3.0) == pytest.approx(math.tan(0.5) * (x - 2.4))  # still on the commanded line


def test_circles_block_and_overlaps_can_escape() -> None:
    c = checker(wall_map(wall_col=190))
    circles = [(2.0, 1.0, 0.3)]
    x, y, _, blocked = c.move(1.0, 1.0, 0.0, 0.31, 0.0, 5.0, circles)
    assert blocked
    assert circles_clearance(x, y, circles) >= R - 1e-9
    assert x == pytest.approx(2.0 - 0.3 - R, abs=c.min_step)
    # placed overlapping the circle: driving away is allowed, driving further in is not
    c.reset()
    assert c.move(1.6, 1.0, math.pi, 0.2, 0.0, 0.5, circles)[3] is False
    c.reset()
    assert c.move(1.6, 1.0, 0.0, 0.2, 0.0, 0.5, circles)[3] is True


def test_static_mask_rasterizes_the_obstacles_that_stand_still() -> None:
    grid = OccupancyMap(np.zeros((100, 100), dtype=np.int8), 0.05, 0.0, 0.0)
    circle = Obstacle(shape="circle", radius=0.5, path=((2.5, 2.5),))
    box = Obstacle(shape="box", size=(1.0, 0.4), yaw=math.pi / 2, path=((1.0, 4.0),))
    mover = Obstacle(shape="circle", radius=0.3, path=((0.5, 0.5), (4.0, 0.5)), speed=0.5)
    mask = static_mask(grid, [circle, box, mover])
    assert mask[50, 50] and not mask[50, 62]  # circle centre in, 0.6 m right out
    assert mask.sum() == pytest.approx(math.pi * 0.5**2 / 0.05**2 + 0.4 / 0.05 * 1.0 / 0.05, rel=0.06)
    r, c = grid.world_to_cell(1.0, 4.45)
    assert mask[r, c]  # the box is rotated: 1 m long along +y
    r, c = grid.world_to_cell(1.45, 4.0)
    assert not mask[r, c]
    r, c = grid.world_to_cell(0.5, 0.5)
    assert not mask[r, c]  # moving obstacles are not rasterized


def test_simulation_with_huge_steps_never_ends_beyond_the_wall() -> None:
    sim = Simulation(wall_map(), (1.0, 1.0, 0.0), (2.0, 3.0, 0.0), physics_dt=0.5)
    for _ in range(20):
        sim.set_velocity_command(0.31, 0.0)
        sim.step()
        assert sim.pose().x < 3.0
    assert sim.pose().x == pytest.approx(3.0 - R, abs=0.01)
    hazards = sim.pop_hazards()
    assert [h.kind for h in hazards] == ["bump"]  # one press while pushing against the wall
    assert hazards[0].x == pytest.approx(sim.pose().x)
    assert sim.velocity() == (0.0, 0.0)
    assert sim.pop_hazards() == []
