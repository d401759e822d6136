"""Named places without DDS: a world's, a destinations file's, lookup by name and alias, and the errors."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tb4.places import DESTINATIONS_ENV, Places, PlacesUnavailable, UnknownPlace


def test_a_worlds_places_by_name_and_alias_whatever_the_case() -> None:
    places = Places.of_world("warehouse")
    assert places.names == ["home", "office", "loading bay", "packing station"]
    assert places.xy_yaw("Packing_Station") == pytest.approx((-12.8, -5.0, math.pi))
    assert places.get("shipping").name == "loading bay" and "LOADING-BAY" in places and "garage" not in places


def test_a_misspelt_place_says_what_was_meant_and_what_there_is() -> None:
    places = Places.of_world("warehouse")
    with pytest.raises(UnknownPlace) as caught:
        places.get("packing statoin")
    text = str(caught.value)
    assert "no place called 'packing statoin' in world warehouse" in text
    assert "did you mean 'packing station'?" in text and "'office'" in text


def test_require_checks_every_name_before_the_robot_moves() -> None:
    places = Places.of_world("warehouse")
    assert [d.name for d in places.require("office", ["home", "packing"])] == ["office", "home", "packing station"]
    with pytest.raises(UnknownPlace) as caught:
        places.require("office", "ofice", "kitchen")  # the first is fine; both bad ones are named at once
    assert (
        "'ofice'" in str(caught.value)
        and "'kitchen'" in str(caught.value)
        and "did you mean 'office'" in str(caught.value)
    )


def test_a_destinations_file_for_a_real_robot(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    site = tmp_path / "lab.yaml"
    site.write_text("destinations:\n  bench: {position: [1.5, 2.0], heading: 90, aliases: [workbench]}\n")
    places = Places.from_file(site)
    assert places.xy_yaw("workbench") == pytest.approx((1.5, 2.0, math.pi / 2))
    monkeypatch.setenv(DESTINATIONS_ENV, str(site))
    assert Places.of_robot(timeout=0.1).names == ["bench"]  # the file wins: no topic is waited for


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("destinations:\n  bench: {position: [1.5]}\n", "destinations.bench.position"),
        ("destinatons: {}\n", "did you mean 'destinations'"),
        ("destinations: [1, 2\n", "lab.yaml"),
    ],
)
def test_a_broken_destinations_file_names_the_file_and_key(tmp_path: Path, text: str, expected: str) -> None:
    site = tmp_path / "lab.yaml"
    site.write_text(text)
    with pytest.raises(PlacesUnavailable) as caught:
        Places.from_file(site)
    assert expected in str(caught.value)


def test_an_unknown_world_is_unavailable_with_a_hint() -> None:
    with pytest.raises(PlacesUnavailable, match="did you mean 'warehouse'"):
        Places.of_world("warehose")
