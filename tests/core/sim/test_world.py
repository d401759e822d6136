"""World files: loading, validation errors, moving obstacles, and that every tutorial goal is usable."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import ndimage

from tb4.config import ConfigError
from tb4.core.maps import OccupancyMap, save_map
from tb4.core.robot_params import robot_radius
from tb4.sim.obstacles import Obstacle, rasterize_obstacles
from tb4.sim.world import WORLDS_DIR, Destination, World, available_worlds, load_world
from tool_modules import load_tool

pytestmark = pytest.mark.core

ROBOT_RADIUS = robot_radius()
GOAL_CLEARANCE = 0.45  # m from any occupied cell (map, static obstacles, moving obstacles' paths)
ERODE = ROBOT_RADIUS + 0.05  # free space the robot centre may use for the reachability check
UNDOCKED = (-0.4, 0.0)  # where undocking (reverse 0.4 m) leaves the robot

# Goals of the upstream tutorials (x, y), in the order they are driven.
TUTORIAL_GOALS: dict[str, list[tuple[float, float]]] = {
    "warehouse": [
        (-13, 9),
        (13, 5),
        (-3, 0),
        (-3, -3),
        (3, -3),
        (9, -1),
        (9, 1),
        (-1, 1),
        (10, 6),
        (-9, 9),
        (-12, 2),
        (3, -7),
        (-5, 1),
        (-5, -23),
        (9, -23),
        (10, 2),
    ],
    "depot": [(-3.3, 5.9), (2.1, 6.3), (2.0, 1.0), (-1.0, 0.0), (0.0, 3.0), (2.0, 2.0), (-6.0, -6.0), (5.0, 5.0)],
    "maze": [],
}
# Straight legs between consecutive goals of each tutorial (start at the undocked pose).
_MAIL = [(-1, 1), (10, 6), (-9, 9), (-12, 2), (3, -7)]
TUTORIAL_LEGS: dict[str, list[list[tuple[float, float]]]] = {
    "warehouse": [
        [UNDOCKED, (-13, 9)],
        [UNDOCKED, (13, 5)],
        [UNDOCKED, (-3, 0), (-3, -3), (3, -3), (9, -1), (9, 1), (-1, 1)],
        [UNDOCKED, (-5, 1), (-5, -23), (9, -23), (10, 2), (-5, 1)],
        *[[a, b] for a in [UNDOCKED, *_MAIL] for b in _MAIL if a != b],
    ],
    "depot": [[UNDOCKED, (-3.3, 5.9), (2.1, 6.3), (2.0, 1.0), (-1.0, 0.0)]],
    "maze": [],
}


@pytest.fixture(scope="module")
def worlds() -> dict[str, World]:
    return {name: load_world(name) for name in ("warehouse", "depot", "maze")}


def _clearance_field(world: World) -> np.ndarray:
    """Distance (m) from every cell centre to the nearest blocked cell (map, static obstacles)."""
    blocked = world.static_obstacle_mask()
    return ndimage.distance_transform_edt(~blocked) * world.map.resolution


def _cell(world: World, x: float, y: float) -> tuple[int, int]:
    return world.map.world_to_cell(x, y)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    t = float(np.clip(np.dot(p - a, ab) / max(np.dot(ab, ab), 1e-12), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + t * ab)))


def _polyline_distance(p: tuple[float, float], pts: tuple[tuple[float, float], ...]) -> float:
    arr = np.asarray(pts, dtype=float)
    return min(_segment_distance(np.asarray(p), arr[i], arr[i + 1]) for i in range(len(arr) - 1))


# ----------------------------------------------------------------------------------------------- loading


def test_shipped_worlds_are_listed_and_load(worlds: dict[str, World]) -> None:
    assert available_worlds() == ["depot", "maze", "warehouse"]
    expected = {
        "warehouse": (0.03, -15.1, -25.0, 1006, 1674),
        "depot": (0.04, -15.1, -7.74, 755, 380),
        "maze": (0.03, -10.1, -10.0, 670, 669),
    }
    for name, (res, ox, oy, w, h) in expected.items():
        world = worlds[name]
        assert world.name == name
        assert world.map.resolution == pytest.approx(res)
        assert (world.map.origin_x, world.map.origin_y) == pytest.approx((ox, oy))
        assert (world.map.width, world.map.height) == (w, h)
        assert world.dock == (0.0, 0.0, 0.0)
        assert world.start == world.dock
        assert world.map_path.parent == WORLDS_DIR
        assert world.source == WORLDS_DIR / f"{name}.yaml"


def test_load_by_path_equals_load_by_name(worlds: dict[str, World]) -> None:
    by_path = load_world(WORLDS_DIR / "depot.yaml")
    by_str = load_world(str(WORLDS_DIR / "depot.yaml"))
    assert by_path.destinations == worlds["depot"].destinations == by_str.destinations
    assert np.array_equal(by_path.map.data, worlds["depot"].map.data)


def test_depot_destinations_match_the_language_tutorial(worlds: dict[str, World]) -> None:
    dests = worlds["depot"].destinations
    expected = {"wood crate": (0.0, 3.0, 0), "steel barrels": (2.0, 2.0, 90), "bathroom door": (-6.0, -6.0, 180)}
    assert set(dests) == set(expected)
    for name, (x, y, heading) in expected.items():
        d = dests[name]
        assert isinstance(d, Destination)
        assert (d.x, d.y) == (x, y)
        assert d.yaw == pytest.approx(math.radians(heading))
        assert d.description
    assert "wooden object" in dests["wood crate"].aliases
    assert "item which can hold oil" in dests["steel barrels"].aliases
    assert "oil drums" in dests["steel barrels"].aliases
    assert "restroom" in dests["bathroom door"].aliases
    assert "toilet" in dests["bathroom door"].description
    world = worlds["depot"]
    assert world.find_destination("  Wooden   Object ") is dests["wood crate"]
    assert world.find_destination("nowhere") is None


def test_depot_objects_are_beside_their_destinations(worlds: dict[str, World]) -> None:
    """The crate, the barrels and the bathroom door are really there, within ~1.2 m of their destinations."""
    world = worlds["depot"]
    occ = world.map.occupied_mask()
    clearance = ndimage.distance_transform_edt(~occ) * world.map.resolution
    for name in ("wood crate", "steel barrels"):
        d = world.destinations[name]
        assert 0.45 <= clearance[_cell(world, d.x, d.y)] <= 1.2, name
    assert world.map.value_at(0.0, 3.9) == 100  # the crate
    assert world.map.value_at(2.7, 2.6) == 100  # a barrel
    # Bathroom door: wall on both sides of the opening, the doorway itself free.
    assert world.map.value_at(-6.55, -6.8) == 100 and world.map.value_at(-6.55, -5.2) == 100
    assert world.map.value_at(-6.55, -6.0) == 0


def test_maze_has_reachable_destinations(worlds: dict[str, World]) -> None:
    world = worlds["maze"]
    assert {"center", "north east corner"} <= set(world.destinations)
    assert not world.obstacles


# ------------------------------------------------------------------------------ goals and free space


@pytest.mark.parametrize("name", ["warehouse", "depot", "maze"])
def test_tutorial_goals_have_clearance_and_are_reachable(worlds: dict[str, World], name: str) -> None:
    world = worlds[name]
    clearance = _clearance_field(world)
    labels, _ = ndimage.label(clearance > ERODE)
    home = labels[_cell(world, *UNDOCKED)]
    assert home > 0, "the undocked pose must be in free space"
    goals = list(TUTORIAL_GOALS[name]) + [(d.x, d.y) for d in world.destinations.values()]
    assert goals
    for x, y in goals:
        cell = _cell(world, x, y)
        assert clearance[cell] >= GOAL_CLEARANCE, f"{name}: goal ({x}, {y}) has {clearance[cell]:.2f} m clearance"
        assert labels[cell] == home, f"{name}: goal ({x}, {y}) is not reachable from the dock"
        for obs in world.moving_obstacles:
            gap = _polyline_distance((x, y), obs.path) - obs.radius
            assert gap >= GOAL_CLEARANCE, f"{name}: goal ({x}, {y}) is on the path of a moving obstacle"


@pytest.mark.parametrize("name", ["warehouse", "depot"])
def test_extra_obstacles_keep_off_tutorial_legs(worlds: dict[str, World], name: str) -> None:
    """Static extra obstacles and moving obstacles' paths stay clear of the straight legs between goals."""
    world = worlds[name]
    assert world.static_obstacles and world.moving_obstacles
    for leg in TUTORIAL_LEGS[name]:
        for a, b in zip(leg[:-1], leg[1:], strict=False):
            for obs in world.static_obstacles:
                centre = np.asarray(obs.path[0])
                gap = _segment_distance(centre, np.asarray(a), np.asarray(b)) - obs.extent()
                assert gap >= 0.5, f"{name}: static obstacle at {obs.path[0]} is {gap:.2f} m from leg {a}->{b}"
            for obs in world.moving_obstacles:
                samples = np.linspace(a, b, 200)
                gap = min(_polyline_distance(tuple(p), obs.path) for p in samples) - obs.radius
                assert gap >= 0.5, f"{name}: moving obstacle path {obs.path} crosses leg {a}->{b}"


@pytest.mark.parametrize("name", ["warehouse", "depot"])
def test_straight_legs_have_room_to_drive(worlds: dict[str, World], name: str) -> None:
    """Driving straight from goal to goal never passes closer than 0.5 m to the map or static obstacles
    (away from the dock, which legs starting at the undocked pose necessarily pass)."""
    world = worlds[name]
    clearance = _clearance_field(world)
    for leg in TUTORIAL_LEGS[name]:
        for a, b in zip(leg[:-1], leg[1:], strict=False):
            pts = np.linspace(a, b, 400)
            pts = pts[np.hypot(pts[:, 0], pts[:, 1]) > 1.0]
            worst = min(clearance[_cell(world, x, y)] for x, y in pts)
            assert worst >= 0.5, f"{name}: leg {a}->{b} passes {worst:.2f} m from an obstacle"


@pytest.mark.parametrize("name", ["warehouse", "depot", "maze"])
def test_dock_station_and_room_to_undock(worlds: dict[str, World], name: str) -> None:
    world = worlds[name]
    grid = world.map
    assert grid.value_at(0.29, 0.0) == 100  # station body ahead of the robot
    assert grid.value_at(0.29, 0.15) == 100 and grid.value_at(0.29, -0.15) == 100
    assert grid.value_at(0.1, 0.0) == 0  # the docked robot itself stands in free space
    # 1.5 m free around and behind the docked robot (except the station body).
    occ = world.static_obstacle_mask()
    ys = grid.origin_y + (np.arange(grid.height) + 0.5) * grid.resolution
    xs = grid.origin_x + (np.arange(grid.width) + 0.5) * grid.resolution
    near = (np.hypot(xs[None, :], ys[:, None]) <= 1.5) & ~(
        (xs[None, :] >= 0.17) & (xs[None, :] <= 0.41) & (np.abs(ys[:, None]) <= 0.22)
    )
    assert not occ[near].any()


@pytest.mark.parametrize("name", ["warehouse", "depot", "maze"])
def test_map_border_is_walled(worlds: dict[str, World], name: str) -> None:
    occ = worlds[name].map.occupied_mask()
    assert occ[0, :].all() and occ[-1, :].all() and occ[:, 0].all() and occ[:, -1].all()


def test_maze_corridors_are_wide_enough(worlds: dict[str, World]) -> None:
    """Every free cell of the maze lies in a passage at least 1.2 m wide (medial-axis clearance >= 0.6 m)."""
    world = worlds["maze"]
    clearance = _clearance_field(world)
    labels, _ = ndimage.label(clearance >= 0.6 - world.map.resolution)
    home = labels[_cell(world, *UNDOCKED)]
    for d in world.destinations.values():
        assert labels[_cell(world, d.x, d.y)] == home, d.name


def test_committed_maps_match_the_drawing_tool() -> None:
    module = load_tool("draw_worlds")
    for name in ("warehouse", "depot", "maze"):
        drawn = module.DRAWERS[name]()
        committed = load_world(name).map
        assert np.array_equal(drawn.data, committed.data), name


# ------------------------------------------------------------------------------------------ obstacles


def test_pingpong_goes_back_and_forth() -> None:
    obs = Obstacle(shape="circle", radius=0.25, path=((0.0, 0.0), (2.0, 0.0), (2.0, 1.0)), speed=0.5)
    assert obs.moving
    assert obs.position_at(0.0) == pytest.approx((0.0, 0.0))
    assert obs.position_at(2.0) == pytest.approx((1.0, 0.0))
    assert obs.position_at(5.0) == pytest.approx((2.0, 0.5))
    assert obs.position_at(6.0) == pytest.approx((2.0, 1.0))  # end of the 3 m polyline
    assert obs.position_at(7.0) == pytest.approx((2.0, 0.5))  # coming back
    assert obs.position_at(10.0) == pytest.approx((1.0, 0.0))
    assert obs.position_at(12.0) == pytest.approx((0.0, 0.0))  # period 2 * 3 m / 0.5 m/s
    assert obs.position_at(12.0 + 2.0) == pytest.approx(obs.position_at(2.0))
    assert obs.position_at(3.3) == obs.position_at(3.3)  # pure function of time


def test_loop_closes_the_polyline() -> None:
    square = ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0))
    obs = Obstacle(shape="circle", radius=0.2, path=square, speed=1.0, mode="loop")
    assert obs.position_at(0.5) == pytest.approx((0.5, 0.0))
    assert obs.position_at(2.5) == pytest.approx((0.5, 1.0))
    assert obs.position_at(3.5) == pytest.approx((0.0, 0.5))  # the closing edge back to the start
    assert obs.position_at(4.0) == pytest.approx((0.0, 0.0))
    assert obs.position_at(4.25) == pytest.approx((0.25, 0.0))


def test_static_obstacle_does_not_move() -> None:
    obs = Obstacle(shape="box", size=(1.0, 0.5), yaw=0.3, path=((2.0, -1.0),))
    assert not obs.moving
    assert obs.position_at(0.0) == obs.position_at(123.4) == (2.0, -1.0)


def test_static_obstacle_mask_includes_obstacles(worlds: dict[str, World]) -> None:
    world = worlds["warehouse"]
    mask = world.static_obstacle_mask()
    assert mask.shape == world.map.data.shape and mask.dtype == bool
    base = world.map.occupied_mask()
    assert (mask | ~base).all()  # everything the map blocks stays blocked
    assert world.map.occupied_mask() is not mask and np.array_equal(world.map.occupied_mask(), base)
    for obs in world.static_obstacles:
        assert mask[_cell(world, *obs.path[0])] and not base[_cell(world, *obs.path[0])]
    for obs in world.moving_obstacles:  # moving obstacles are not in the static mask
        assert not mask[_cell(world, *obs.position_at(0.0))]


def test_rasterize_box_respects_heading() -> None:
    grid = OccupancyMap(np.zeros((100, 100), dtype=np.int8), 0.05, origin_x=-2.5, origin_y=-2.5)
    box = Obstacle(shape="box", size=(2.0, 0.4), yaw=math.pi / 2, path=((0.0, 0.0),))
    mask = rasterize_obstacles(grid, [box])
    assert mask[grid.world_to_cell(0.0, 0.9)] and not mask[grid.world_to_cell(0.9, 0.0)]
    assert mask.sum() == pytest.approx((2.0 * 0.4) / 0.05**2, rel=0.15)
    circle = Obstacle(shape="circle", radius=0.5, path=((1.0, 1.0),))
    mask = rasterize_obstacles(grid, [circle])
    assert mask.sum() == pytest.approx(math.pi * 0.25 / 0.05**2, rel=0.1)


# ----------------------------------------------------------------------------------------- validation


def _world_dir(tmp_path: Path) -> Path:
    """A 10 x 10 m free map with a wall block at x 2..3, y 2..3, origin (-5, -5)."""
    data = np.zeros((100, 100), dtype=np.int8)
    data[70:80, 70:80] = 100
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    save_map(OccupancyMap(data, 0.1, origin_x=-5.0, origin_y=-5.0), tmp_path / "small_map.yaml")
    return tmp_path


def _write(tmp_path: Path, body: str) -> Path:
    _world_dir(tmp_path)
    path = tmp_path / "small.yaml"
    path.write_text("map: small_map.yaml\ndock: [0, 0, 0]\n" + body, encoding="utf-8")
    return path


def test_minimal_world_file_loads(tmp_path: Path) -> None:
    path = _write(
        tmp_path,
        "start: [1, 1, 90]\n"
        "destinations:\n  spot: {position: [-2, -2], heading: 45, aliases: [place]}\n"
        "obstacles:\n"
        "  - {shape: box, position: [-3, 3], size: [1, 0.5], heading: 30}\n"
        "  - {shape: circle, radius: 0.2, path: [[-4, -4], [-4, 4], [4, -4]], speed: 0.5, mode: loop}\n",
    )
    world = load_world(path)
    assert world.name == "small"
    assert world.start == pytest.approx((1.0, 1.0, math.pi / 2))
    assert world.destinations["spot"].yaw == pytest.approx(math.pi / 4)
    assert world.obstacles[0].yaw == pytest.approx(math.radians(30))
    assert world.obstacles[1].moving and world.obstacles[1].mode == "loop"
    assert not world.obstacles[0].moving


@pytest.mark.parametrize(
    ("body", "key", "fragment"),
    [
        ("destinatons: {}\n", "destinatons", "did you mean 'destinations'"),
        ("destinations:\n  spot: {positon: [1, 1]}\n", "destinations.spot.positon", "did you mean 'position'"),
        ("destinations:\n  spot: {position: [1, 1], heading: north}\n", "destinations.spot.heading", "number"),
        ("destinations:\n  spot: {position: [1]}\n", "destinations.spot.position", "[x, y]"),
        ("destinations:\n  spot: {position: [2.5, 2.5]}\n", "destinations.spot.position", "'spot'"),
        ("destinations:\n  spot: {position: [20, 0]}\n", "destinations.spot.position", "outside the map"),
        ("destinations:\n  a: {position: [1, 1]}\n  b: {position: [-1, 1], aliases: [a]}\n", "destinations.b", "a"),
        ("obstacles:\n  - {shape: circel, position: [1, 1], radius: 0.2}\n", "obstacles[0].shape", "circle"),
        ("obstacles:\n  - {shape: box, position: [1, 1]}\n", "obstacles[0].size", "missing"),
        ("obstacles:\n  - {shape: box, position: [1, 1], size: [1, 1], radius: 1}\n", "obstacles[0].radius", "box"),
        ("obstacles:\n  - {shape: circle, radius: 0.2, path: [[0, 1], [1, 1]]}\n", "obstacles[0].speed", "missing"),
        (
            "obstacles:\n  - {shape: circle, radius: 0.2, path: [[0, 1], [1, 1]], speed: 1, mode: bounce}\n",
            "obstacles[0].mode",
            "pingpong",
        ),
        (
            "obstacles:\n  - {shape: box, size: [1, 1], path: [[0, 1], [1, 1]], speed: 1}\n",
            "obstacles[0].shape",
            "circles",
        ),
        ("obstacles:\n  - {shape: circle, radius: 0.2}\n", "obstacles[0]", "either 'position'"),
        ("obstacles:\n  - {shape: circle, radius: 0.5, position: [1, 1]}\nstart: [1.2, 1, 0]\n", "start", "inside"),
        ("start: parked\n", "start", "docked"),
        ("obstacles:\n  - {shape: circle, radius: 0.2, position: [9, 1]}\n", "obstacles[0].position", "outside"),
        (
            "obstacles:\n  - {shape: circle, radius: 0.2, path: [[0, 1], [1, 9]], speed: 1}\n",
            "obstacles[0].path[1]",
            "outside",
        ),
    ],
)
def test_bad_world_files_name_the_key(tmp_path: Path, body: str, key: str, fragment: str) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(ConfigError) as info:
        load_world(path)
    assert info.value.key == key
    assert info.value.source == str(path)
    assert fragment in str(info.value)


def test_destination_in_a_wall_is_named(tmp_path: Path) -> None:
    path = _write(tmp_path, "destinations:\n  the shelf: {position: [2.5, 2.5]}\n")
    with pytest.raises(ConfigError, match=r"destination 'the shelf' \(2.5, 2.5\) is in an occupied cell"):
        load_world(path)


def test_missing_map_and_missing_dock(tmp_path: Path) -> None:
    (tmp_path / "w.yaml").write_text("map: nowhere.yaml\ndock: [0, 0, 0]\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="map file not found") as info:
        load_world(tmp_path / "w.yaml")
    assert info.value.key == "map"
    _world_dir(tmp_path)
    (tmp_path / "w.yaml").write_text("map: small_map.yaml\n", encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_world(tmp_path / "w.yaml")
    assert info.value.key == "dock"


def test_unknown_world_name_lists_available_worlds() -> None:
    with pytest.raises(ConfigError) as info:
        load_world("warehuose")
    message = str(info.value)
    assert "did you mean 'warehouse'" in message
    for name in ("depot", "maze", "warehouse"):
        assert name in message
    with pytest.raises(ConfigError, match="available worlds"):
        load_world("mars")


def test_track_is_closed_in_loop_mode() -> None:
    path = ((0.0, 0.0), (1.0, 0.0), (1.0, 1.0))
    loop = Obstacle(shape="circle", radius=0.2, path=path, speed=1.0, mode="loop")
    pingpong = Obstacle(shape="circle", radius=0.2, path=path, speed=1.0)
    assert loop.track().tolist() == [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 0.0]]
    assert pingpong.track().tolist() == [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]
