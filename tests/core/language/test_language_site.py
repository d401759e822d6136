"""gpt_node's site: destinations from a file of its own (a real robot) or from a simulator world."""

from __future__ import annotations

from pathlib import Path

import pytest

from tb4.config import ConfigError
from tb4.language.site import load_site, load_site_file, site_from_world
from tb4.language.world_context import DOCK_DESTINATION, destination_table, pose_checker
from tb4.sim.world import WORLDS_DIR, load_world


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "site.yaml"
    path.write_text(text)
    return path


def test_a_file_without_a_map_checks_only_finiteness(tmp_path: Path) -> None:
    site = load_site_file(_write(tmp_path, "destinations:\n  lab: {position: [100.0, -40.0], heading: 180}\n"))
    assert site.name == "site" and site.map is None and site.dock is None
    assert destination_table(site) == {"lab": [100.0, -40.0, 180.0]}  # no dock pose: no 'dock' destination
    check = pose_checker(site)
    assert check(100.0, -40.0) is None and check(float("nan"), 0.0) == "coordinates are not finite"


def test_a_file_with_a_map_and_dock_checks_goals_like_a_world(tmp_path: Path) -> None:
    text = (
        f"name: lab\nmap: {WORLDS_DIR / 'depot_map.yaml'}\ndock: [0.0, 0.0, 0.0]\n"
        "destinations:\n  crate: {position: [0.0, 3.0]}\n"
    )
    site = load_site_file(_write(tmp_path, text))
    assert DOCK_DESTINATION in destination_table(site)
    check = pose_checker(site)
    assert check(0.0, 3.0) is None
    assert "outside the map" in (check(1000.0, 0.0) or "")


def test_a_destination_in_a_wall_or_a_misspelt_key_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="did you mean"):
        load_site_file(_write(tmp_path, "destinatons: {}\n"))
    text = f"map: {WORLDS_DIR / 'depot_map.yaml'}\ndestinations:\n  far: {{position: [1000.0, 0.0]}}\n"
    with pytest.raises(ConfigError, match="outside the map"):
        load_site_file(_write(tmp_path, text))


def test_the_world_is_one_source_and_agrees_with_the_file_route() -> None:
    world = load_world("depot")
    assert destination_table(site_from_world(world)) == destination_table(world)
    assert load_site("", "depot").destinations.keys() == world.destinations.keys()
    with pytest.raises(ConfigError):
        load_site("", "")
