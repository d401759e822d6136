"""tb4.wire speaks whichever nav2_msgs is installed: the same calls build and read Kilted's and Jazzy's messages.

Run in the Kilted environment and in the Jazzy one (`make test` does both); each message is put through rclpy's
serializer, so what is checked is what goes on the wire.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import BackUp, ComputePathThroughPoses, FollowWaypoints, NavigateThroughPoses, Spin
from nav2_msgs.srv import IsPathValid
from rclpy.serialization import deserialize_message, serialize_message

from tb4.wire import (
    WIRE_FORMATS,
    get_optional,
    get_poses,
    has_field,
    missed_waypoint,
    missed_waypoint_fields,
    set_poses,
    set_supported,
    wire_format,
)


def _pose(x: float, y: float, frame: str = "map") -> PoseStamped:
    pose = PoseStamped()
    pose.header.frame_id = frame
    pose.pose.position.x, pose.pose.position.y = x, y
    return pose


def _over_the_wire(msg):
    return deserialize_message(serialize_message(msg), type(msg))


def test_the_installed_format_is_known_and_consistent() -> None:
    fmt = wire_format()
    assert fmt in WIRE_FORMATS
    kilted = fmt == "kilted"
    assert has_field(NavigateThroughPoses.Result, "waypoint_statuses") is kilted
    assert has_field(Spin.Goal, "disable_collision_checks") is kilted
    assert has_field(IsPathValid.Request, "max_cost") is kilted
    entry = FollowWaypoints.Result.get_fields_and_field_types()["missed_waypoints"]
    assert entry == ("sequence<nav2_msgs/WaypointStatus>" if kilted else "sequence<nav2_msgs/MissedWaypoint>")


@pytest.mark.parametrize(("action", "field"), [(NavigateThroughPoses, "poses"), (ComputePathThroughPoses, "goals")])
def test_pose_lists_round_trip(action, field) -> None:
    goal = action.Goal()
    poses = [_pose(1.0, 2.0), _pose(-3.5, 0.25)]
    set_poses(goal, field, poses)
    back = get_poses(_over_the_wire(goal), field)
    assert [(p.pose.position.x, p.pose.position.y, p.header.frame_id) for p in back] == [
        (1.0, 2.0, "map"),
        (-3.5, 0.25, "map"),
    ]


def test_an_empty_pose_list_is_still_a_valid_message() -> None:
    goal = NavigateThroughPoses.Goal()
    set_poses(goal, "poses", [])
    assert get_poses(_over_the_wire(goal), "poses") == []


def test_fields_only_one_format_has() -> None:
    goal = BackUp.Goal()
    missing = set_supported(goal, disable_collision_checks=True, speed=0.1)
    assert math.isclose(goal.speed, 0.1, rel_tol=1e-6)
    if wire_format() == "kilted":
        assert missing == [] and goal.disable_collision_checks is True
    else:
        assert missing == ["disable_collision_checks"]
    request = IsPathValid.Request()
    assert get_optional(request, "max_cost", 254) == 254  # upstream's default, in both formats
    assert get_optional(request, "consider_unknown_as_obstacle", False) is False


def test_missed_waypoints_round_trip() -> None:
    result = FollowWaypoints.Result()
    result.missed_waypoints = [missed_waypoint(2, _pose(4.0, 5.0), 601, "blocked")]
    (entry,) = _over_the_wire(result).missed_waypoints
    index, pose, code, message = missed_waypoint_fields(entry)
    assert (index, pose.pose.position.x, code) == (2, 4.0, 601)
    assert message == ("blocked" if wire_format() == "kilted" else "")  # Jazzy's MissedWaypoint has no message


def test_kilted_only_codes_are_kilteds_values() -> None:
    """The numbers sent for codes Jazzy does not declare are Kilted's, read from the Kilted reference."""
    import pathlib
    import re

    from tb4 import wire

    text = (pathlib.Path(__file__).resolve().parents[1] / "data" / "reference" / "interfaces-full.md").read_text()
    for (action, name), value in wire._KILTED_ONLY_CODES.items():
        section = text.split(f"## nav2_msgs/action/{action}.action\n", 1)[1].split("\n## ", 1)[0]
        result = section.split("\n---\n")[1]
        match = re.search(rf"^uint16 {name}=(\d+)", result, re.M)
        assert match and int(match.group(1)) == value, (action, name)
    from nav2_msgs import action as actions

    for action, name in wire._KILTED_ONLY_CODES:
        assert wire.result_code(getattr(actions, action), name) == wire._KILTED_ONLY_CODES[(action, name)]


def test_the_type_support_libraries_loaded_are_those_of_the_imported_nav2_msgs() -> None:
    """The Jazzy environment overlays the Kilted one, which holds Kilted's nav2_msgs libraries under the same names:
    the dynamic loader must take the overlay's, the ones built with the Python package that was imported."""
    import nav2_msgs
    from rclpy.type_support import check_for_type_support

    for action in (BackUp, ComputePathThroughPoses, FollowWaypoints, NavigateThroughPoses, Spin):
        check_for_type_support(action)  # loads the action's C type support, and with it the package's libraries
    prefix = Path(nav2_msgs.__file__).resolve().parents[4]  # <prefix>/lib/pythonX.Y/site-packages/nav2_msgs
    with open("/proc/self/maps", encoding="utf-8") as maps:
        loaded = {Path(line.split()[-1]) for line in maps if "libnav2_msgs__" in line}
    assert loaded, "no nav2_msgs library was loaded"
    assert {path.parent for path in loaded} == {prefix / "lib"}, loaded
