"""The viewer's latest-value state and what one page's snapshots contain, without DDS."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from PIL import Image

from tb4.core.geometry import compose
from tb4.viewer.grid_image import COSTMAP_PALETTE, MAP_PALETTE, Grid, encode_indexed_png, grid_png
from tb4.viewer.state import ClientCursor, ViewerState
from tb4.viewer.tracking import RealTimeFactor, TaskTracker, Trail


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def _decode(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))


def test_indexed_png_round_trips_through_a_real_decoder() -> None:
    pixels = np.arange(256, dtype=np.uint8).reshape(16, 16)
    rgba = _decode(encode_indexed_png(pixels, COSTMAP_PALETTE))
    assert rgba.shape == (16, 16, 4)
    assert np.array_equal(rgba, COSTMAP_PALETTE[pixels])


def test_grid_png_puts_the_highest_row_on_top_and_colours_by_value() -> None:
    data = np.zeros((3, 4), dtype=np.int8)
    data[0, 0] = 100  # bottom-left cell occupied
    data[2, 3] = -1  # top-right cell unknown
    rgba = _decode(grid_png(Grid(data, 0.05, 0.0, 0.0), MAP_PALETTE))
    assert tuple(rgba[2, 0]) == tuple(MAP_PALETTE[100])  # image bottom row = grid row 0
    assert tuple(rgba[0, 3]) == tuple(MAP_PALETTE[255])
    assert rgba[1, 1, 0] > 240  # free is near white
    assert rgba[2, 0, 0] < 40  # occupied is near black
    assert COSTMAP_PALETTE[0, 3] == 0 and COSTMAP_PALETTE[255, 3] == 0  # free/unknown cost: transparent


def test_png_encoder_rejects_empty_images() -> None:
    with pytest.raises(ValueError):
        encode_indexed_png(np.zeros((0, 3), dtype=np.uint8), MAP_PALETTE)


def test_compose_applies_the_parent_transform() -> None:
    x, y, yaw = compose((1.0, 2.0, math.pi / 2), (1.0, 0.0, math.pi / 2))
    assert (x, y) == pytest.approx((1.0, 3.0))
    assert abs(yaw) == pytest.approx(math.pi)


def test_real_time_factor_from_sim_and_wall_time() -> None:
    clock = FakeClock()
    rtf = RealTimeFactor(window=2.0, clock=clock)
    assert rtf.value() is None
    for i in range(30):
        clock.now = i * 0.1
        rtf.add(sim_time=i * 0.1 * 8.0)
    assert rtf.value() == pytest.approx(8.0)
    clock.now = 10.0  # clock stopped (simulator paused or gone)
    assert rtf.value() == 0.0
    rtf.add(sim_time=0.5)  # a restarted simulator: old samples dropped
    assert rtf.value() is None


def test_trail_is_bounded_spaced_and_incremental() -> None:
    trail = Trail(maxlen=10, step=0.1)
    for i in range(100):
        trail.add(i * 0.01, 0.0)  # 1 m in 1 cm steps -> points every 10 cm
    assert 9 <= trail.seq <= 11 and len(trail.points) <= 10
    reset, flat, seq = trail.since(-1, 0)
    assert reset and len(flat) == 2 * len(trail.points)
    trail.add(1.2, 0.0)
    reset, flat, seq2 = trail.since(trail.epoch, seq)
    assert not reset and flat == [1.2, 0.0] and seq2 == seq + 1
    trail.add(9.0, 9.0)  # far apart samples (a fast simulator) continue the trail
    assert not trail.since(trail.epoch, seq2)[0]
    trail.clear()
    reset, flat, _ = trail.since(trail.epoch - 1, seq2)
    assert reset and flat == []
    trail.add(math.nan, 0.0)
    assert len(trail.points) == 0


def test_a_new_initial_pose_restarts_the_trail_but_small_corrections_do_not() -> None:
    state = ViewerState()
    state.set_map_odom((0.0, 0.0, 0.0))
    for i in range(10):
        state.set_odom_base((i * 0.1, 0.0, 0.0))
    assert len(state.snapshot(ClientCursor())["trail"]["points"]) == 20
    state.set_map_odom((0.05, 0.0, 0.02))  # a localization correction
    state.set_odom_base((1.0, 0.0, 0.0))
    assert len(state.snapshot(ClientCursor())["trail"]["points"]) == 22
    state.set_map_odom((3.0, 1.0, 0.0))  # relocalized
    state.set_odom_base((1.1, 0.0, 0.0))
    assert state.snapshot(ClientCursor())["trail"]["points"] == [4.1, 1.0]


def test_task_tracker_reports_the_active_goal_then_the_last_finished_one() -> None:
    clock = FakeClock()
    tasks = TaskTracker(clock=clock)
    assert tasks.current() is None
    assert tasks.on_status("navigate_to_pose", [("a", 2)]) == [("a", 2)]
    clock.now = 1.0
    tasks.on_feedback("navigate_to_pose", "a", {"distance_remaining": 4.0, "eta": 12.0})
    current = tasks.current()
    assert current is not None and current["status"] == "executing" and current["distance_remaining"] == 4.0
    clock.now = 2.0
    assert tasks.on_status("navigate_to_pose", [("a", 4)]) == [("a", 4)]
    assert tasks.on_status("navigate_to_pose", [("a", 4)]) == []  # unchanged: not reported again
    tasks.on_feedback("navigate_to_pose", "a", {"distance_remaining": 99.0})  # late feedback ignored
    current = tasks.current()
    assert current is not None and current["status"] == "succeeded" and not current["active"]
    assert current["distance_remaining"] == 4.0
    for i in range(100):  # bounded memory
        tasks.on_status("spin", [(f"g{i}", 4)])
    assert len(tasks._goals) <= TaskTracker.MAX_GOALS


def test_snapshot_composes_the_robot_pose_and_sends_changes_once() -> None:
    clock = FakeClock()
    state = ViewerState("/robot1", clock=clock)
    cursor = ClientCursor()
    first = state.snapshot(cursor)
    assert first["robot"] is None and first["namespace"] == "/robot1" and "plan" not in first

    state.set_odom_base((1.0, 0.0, 0.0))
    robot = state.snapshot(cursor)["robot"]
    assert robot["localized"] is False and robot["frame"] == "odom" and robot["x"] == 1.0
    state.set_map_odom((2.0, 3.0, math.pi / 2))
    state.set_scan(np.array([1.0, np.inf, 0.01], dtype=np.float32), 0.0, math.pi / 2, 0.15, 12.0)
    state.set_plan(np.array([[2.0, 4.0, 0.0], [5.0, 5.0, 1.0]]))
    state.notice("warn", "goal aborted")
    snap = state.snapshot(cursor)
    assert snap["robot"]["localized"] is True
    assert (snap["robot"]["x"], snap["robot"]["y"]) == pytest.approx((2.0, 4.0))
    assert snap["scan"] == pytest.approx([2.0, 5.0])  # the one valid beam, 1 m straight ahead (map +y)
    assert snap["plan"]["points"] == [2.0, 4.0, 5.0, 5.0]
    assert snap["goal"] == {"x": 5.0, "y": 5.0, "yaw": 1.0, "source": "plan"}
    assert snap["notices"] == [{"level": "warn", "text": "goal aborted"}]
    again = state.snapshot(cursor)
    assert "plan" not in again and "notices" not in again and "trail" not in again


def test_a_page_goal_is_kept_when_the_plan_ends_near_it() -> None:
    state = ViewerState()
    state.set_goal(3.0, 3.0, 0.5, "page")
    state.set_plan(np.array([[0.0, 0.0, 0.0], [3.1, 3.0, 0.0]]))
    assert state.snapshot(ClientCursor())["goal"]["source"] == "page"
    state.set_plan(np.array([[0.0, 0.0, 0.0], [9.0, 9.0, 0.0]]))  # someone else's goal
    assert state.snapshot(ClientCursor())["goal"]["source"] == "plan"


def test_long_plans_are_decimated_but_keep_their_end() -> None:
    state = ViewerState()
    plan = np.column_stack([np.linspace(0, 100, 5001), np.zeros(5001), np.zeros(5001)])
    state.set_plan(plan)
    points = state.snapshot(ClientCursor())["plan"]["points"]
    assert len(points) // 2 <= 402
    assert points[-2:] == [100.0, 0.0]


def test_layers_are_sent_when_new_and_not_more_often_than_their_interval() -> None:
    clock = FakeClock()
    state = ViewerState(clock=clock)
    cursor = ClientCursor()
    assert state.layers_due(cursor, ["map", "local_costmap"]) == []
    grid = Grid(np.zeros((4, 4), dtype=np.int8), 0.05, 0.0, 0.0)
    state.set_layer("map", grid)
    state.set_layer("local_costmap", grid)
    assert state.layers_due(cursor, ["map", "local_costmap"]) == ["map", "local_costmap"]
    for name in ("map", "local_costmap"):
        version, _, png = state.layer_png(name) or (0, None, b"")
        assert png.startswith(b"\x89PNG")
        cursor.layer_versions[name] = version
        cursor.layer_sent_at[name] = clock.now
    assert state.layers_due(cursor, ["map", "local_costmap"]) == []
    state.set_layer("local_costmap", grid)  # the same data again: no new version
    assert state.layers_due(cursor, ["local_costmap"]) == []
    changed = Grid(np.full((4, 4), 50, dtype=np.int8), 0.05, 0.0, 0.0)
    state.set_layer("local_costmap", changed)
    clock.now = 0.1
    assert state.layers_due(cursor, ["local_costmap"]) == []  # too soon after the last send
    clock.now = 0.3
    assert state.layers_due(cursor, ["local_costmap"]) == ["local_costmap"]
    with pytest.raises(ValueError):
        state.set_layer("everything", grid)


def test_world_is_sent_once_per_change() -> None:
    state = ViewerState()
    cursor = ClientCursor()
    assert state.snapshot(cursor)["world"] is None  # first snapshot says "no world known"
    assert "world" not in state.snapshot(cursor)
    state.set_world({"name": "warehouse", "dock": {"x": 0, "y": 0, "yaw": 0}, "destinations": []})
    assert state.snapshot(cursor)["world"]["name"] == "warehouse"
    assert "world" not in state.snapshot(cursor)


def test_announced_goals_become_goal_and_waypoints_and_plans_towards_them_keep_them() -> None:
    state = ViewerState()
    state.set_goals([(1.0, 0.0, 0.0), (2.0, 1.0, 0.0), (3.0, 3.0, 1.5)])
    snap = state.snapshot(ClientCursor())
    assert snap["goal"] == {"x": 3.0, "y": 3.0, "yaw": 1.5, "source": "goals"}
    assert [(w["x"], w["y"]) for w in snap["waypoints"]] == [(1.0, 0.0), (2.0, 1.0), (3.0, 3.0)]
    state.set_plan(np.array([[0.0, 0.0, 0.0], [1.1, 0.1, 0.0]]))  # towards the first waypoint
    assert state.snapshot(ClientCursor())["goal"]["source"] == "goals"
    state.set_goals([(5.0, 5.0, 0.0), (math.nan, 0.0, 0.0)])  # a single valid pose: a goal, no waypoints
    snap = state.snapshot(ClientCursor())
    assert snap["goal"]["x"] == 5.0 and snap["waypoints"] == []


def test_a_fleet_robot_is_drawn_at_its_true_pose_until_localized_and_gives_an_overview() -> None:
    state = ViewerState("/robot2")
    state.set_odom_base((0.0, 0.0, 0.0))  # its odom frame starts where it started: not the map's origin
    state.set_fleet(("/robot1", "/robot2"))
    assert state.robot_pose() is None  # not at odom's origin, and its true pose is not known yet
    state.set_truth((0.0, 1.0, 0.0))
    cursor = ClientCursor()
    overview = state.overview(cursor)
    assert overview["robot"]["y"] == 1.0 and overview["robot"]["frame"] == "truth"
    assert not overview["robot"]["localized"]
    state.set_plan(np.array([[0.0, 1.0, 0.0], [2.0, 1.0, 0.0]]))
    assert state.overview(cursor)["plan"] == [0.0, 1.0, 2.0, 1.0]
    assert "plan" not in state.overview(cursor)  # sent once per version
    state.set_map_odom((0.0, 1.0, 0.0))  # localized: drawn from tf as always
    state.set_odom_base((0.5, 0.0, 0.0))
    assert state.robot_pose() == (0.5, 1.0, 0.0)
    assert state.overview(cursor)["robot"]["frame"] == "map"


def test_a_robot_another_robots_fleet_names_is_never_drawn_from_odometry_before_its_own_fleet_message() -> None:
    state = ViewerState("/robot2")
    state.set_odom_base((0.0, 0.0, 0.0))  # odom first: as a lone robot it would be drawn at the map's origin
    state.join_fleet(("/robot1", "/robot2"))  # the commanded robot's fleet names it
    assert state.robot_pose() is None and state.overview(ClientCursor())["robot"] is None
    state.set_odom_base((0.1, 0.0, 0.0))
    assert state.overview(ClientCursor()).get("trail", {}).get("points", []) == []  # nor a trail in its odom frame
    state.set_truth((0.0, 1.0, 0.0))
    assert state.overview(ClientCursor())["robot"]["y"] == 1.0
    state.join_fleet(("/robot1",))  # once it has a fleet, what another robot's fleet says changes nothing
    assert state.fleet == ("/robot1", "/robot2")
    state.set_fleet(("/robot1", "/robot2", "/robot3"))  # its own fleet message always counts
    assert state.fleet == ("/robot1", "/robot2", "/robot3")


def test_a_robot_in_no_fleet_is_drawn_from_odometry_until_localized_as_before() -> None:
    state = ViewerState("")
    state.set_odom_base((0.2, 0.0, 0.0))
    state.set_truth((5.0, 5.0, 0.0))  # never used without a fleet
    assert state.robot_pose() == (0.2, 0.0, 0.0)
    assert state.snapshot(ClientCursor())["robot"]["frame"] == "odom"
