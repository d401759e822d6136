"""The viewer shows the world the simulator announces (by name or file), and nothing when there is none."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from tb4.sim.world import WORLDS_DIR, load_world
from tb4.viewer.world_info import WorldInfoCache, world_info

pytestmark = pytest.mark.core


def test_a_shipped_world_by_name_and_none_without_a_reference() -> None:
    cache = WorldInfoCache()
    info = cache.get("depot")
    assert info is not None and info["name"] == "depot"
    assert [d["name"] for d in info["destinations"]] == list(load_world("depot").destinations)
    assert cache.get("depot") is info  # loaded once
    assert cache.get("") is None  # the map changed under the world, or a real robot


def test_every_dock_of_the_world_in_order_labelled_and_the_first_as_dock() -> None:
    world = load_world("warehouse")
    info = world_info(world)
    assert len(world.all_docks) == 5  # a fleet's robots start on the first ones
    assert [(d["x"], d["y"], d["yaw"]) for d in info["docks"]] == list(world.all_docks)
    assert [d["label"] for d in info["docks"]] == ["dock 1", "dock 2", "dock 3", "dock 4", "dock 5"]
    x, y, yaw = world.dock
    assert info["dock"] == {"x": x, "y": y, "yaw": yaw}  # the one-dock form, for pages that know only it


def test_a_world_with_one_dock_gives_one_dock_labelled_dock(tmp_path: Path) -> None:
    path = tmp_path / "one_dock.yaml"
    path.write_text(f"map: {WORLDS_DIR / 'warehouse_map.yaml'}\ndock: [0.0, 1.0, 90]\n", encoding="utf-8")
    info = WorldInfoCache().get(str(path))
    assert info is not None
    assert info["docks"] == [{"x": 0.0, "y": 1.0, "yaw": pytest.approx(math.pi / 2), "label": "dock"}]
    assert info["dock"] == {"x": 0.0, "y": 1.0, "yaw": pytest.approx(math.pi / 2)}


def test_a_world_that_does_not_load_gives_none_and_the_reason(tmp_path: Path) -> None:
    cache = WorldInfoCache()
    missing = str(tmp_path / "elsewhere.yaml")  # e.g. a file on the simulator's machine only
    assert cache.get(missing) is None and "elsewhere" in cache.errors[missing]


def test_the_simulator_names_shipped_worlds_and_gives_other_worlds_by_path(tmp_path: Path) -> None:
    world_topic = pytest.importorskip("tb4.ros.world_topic")
    assert world_topic.world_reference(load_world("maze")) == "maze"
    for name in ("depot.yaml", "depot_map.yaml", "depot_map.pgm", "depot_graph.geojson"):
        shutil.copy(WORLDS_DIR / name, tmp_path / name)
    copy = load_world(tmp_path / "depot.yaml")
    reference = world_topic.world_reference(copy)
    assert reference == str((tmp_path / "depot.yaml").resolve())
    assert WorldInfoCache().get(reference) is not None


def test_the_fleet_topic_names_every_robot_once_in_order() -> None:
    world_topic = pytest.importorskip("tb4.ros.world_topic")
    fleet = ("/robot1", "/robot2", "/robot3")
    assert world_topic.parse_fleet(world_topic.fleet_text(fleet)) == fleet
    assert world_topic.parse_fleet("  /robot2 junk /robot2 /robot1 ") == ("/robot2", "/robot1")
    assert world_topic.parse_fleet("") == ()
    # anyone on the domain can publish it: malformed names are dropped, and the count is bounded
    hostile = "/ok /1bad /a//b /has$dollar /" + "x" * 70 + " /tail/ " + " ".join(f"/r{i}" for i in range(10_000))
    parsed = world_topic.parse_fleet(hostile)
    assert parsed[0] == "/ok" and len(parsed) == world_topic.MAX_FLEET
    assert not {"/1bad", "/a//b", "/has$dollar", "/tail/"} & set(parsed)
