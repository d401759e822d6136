"""The standard types under Jazzy's nav2_msgs are the same in the Kilted wheels we build on (comments aside).

Our Jazzy build compiles Nav2 Jazzy's nav2_msgs against the Kilted wheels' geometry_msgs, nav_msgs, std_msgs,
builtin_interfaces, action_msgs, unique_identifier_msgs and service_msgs. That is only Jazzy's wire format if those
definitions are Jazzy's too: each one Jazzy's nav2_msgs reaches is kept, as ROS 2 Jazzy defines it, in
tests/data/reference/jazzy-standard/ and compared here with the definition installed from the wheels. (Kilted adds
nav_msgs/Goals, which only Kilted's nav2_msgs uses.)
"""

from __future__ import annotations

import pathlib

import pytest

from tb4.rosenv import share_directories

JAZZY = pathlib.Path(__file__).resolve().parents[1] / "data" / "reference" / "jazzy-standard"
FILES = sorted(p.relative_to(JAZZY) for p in JAZZY.rglob("*") if p.suffix in (".msg", ".srv"))


def _fields(text: str) -> list[str]:
    """The definition without comments and blank lines, white space folded: what makes the type."""
    lines = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].split()
        if line:
            lines.append(" ".join(line))
    return lines


def test_the_reference_covers_what_nav2_msgs_uses() -> None:
    names = {f"{p.parts[0]}/{p.stem}" for p in FILES}
    for needed in ("geometry_msgs/PoseStamped", "nav_msgs/Path", "nav_msgs/OccupancyGrid", "std_msgs/Header"):
        assert needed in names
    assert "action_msgs/CancelGoal" in names and "unique_identifier_msgs/UUID" in names


@pytest.mark.parametrize("rel", FILES, ids=str)
def test_kilted_wheels_define_it_as_jazzy_does(rel: pathlib.Path) -> None:
    # the first definition the environment holds (the Jazzy environment overlays the Kilted one, whose these are)
    installed = next((share / rel for share in share_directories() if (share / rel).is_file()), None)
    assert installed is not None, f"{rel} is not installed under {share_directories()}"
    assert _fields(installed.read_text()) == _fields((JAZZY / rel).read_text())
