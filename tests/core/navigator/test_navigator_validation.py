"""Argument checks and timeout settings, without DDS: bad input fails before anything is sent."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("nav2_msgs.msg", reason="interface packages not built")

from geometry_msgs.msg import PoseStamped  # noqa: E402
from nav_msgs.msg import Goals, Path  # noqa: E402

from tb4.navigator import NavigatorTimeouts  # noqa: E402
from tb4.navigator._validate import check_number, check_path, check_pose_stamped, check_poses  # noqa: E402
from tb4.navigator.results import TaskResult, status_name, task_result_of  # noqa: E402


def pose(x: float = 0.0, y: float = 0.0) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = x, y
    return msg


def test_pose_checks() -> None:
    assert check_pose_stamped(pose(1, 2)).pose.position.x == 1
    with pytest.raises(ValueError, match="position.x must be finite"):
        check_pose_stamped(pose(math.nan, 0))
    with pytest.raises(ValueError, match="position.y"):
        check_pose_stamped(pose(0, math.inf))
    zero = pose()
    zero.pose.orientation.w = 0.0
    with pytest.raises(ValueError, match="zero quaternion"):
        check_pose_stamped(zero)
    with pytest.raises(TypeError, match="getPoseStamped"):
        check_pose_stamped([1.0, 2.0])


def test_pose_lists_accept_lists_and_goals() -> None:
    assert len(check_poses([pose(), pose(1, 1)])) == 2
    assert len(check_poses(Goals(goals=[pose()]))) == 1
    with pytest.raises(ValueError, match="empty"):
        check_poses([])
    with pytest.raises(TypeError):
        check_poses(pose())
    with pytest.raises(ValueError, match=r"poses\[1\]"):
        check_poses([pose(), pose(math.nan)])
    with pytest.raises(ValueError, match="no poses"):
        check_path(Path())


def test_numbers() -> None:
    assert check_number(3, "x") == 3.0
    with pytest.raises(TypeError):
        check_number("3", "x")
    with pytest.raises(TypeError):
        check_number(True, "x")
    with pytest.raises(ValueError, match="positive"):
        check_number(0, "speed", positive=True)


def test_timeouts_are_bounded() -> None:
    t = NavigatorTimeouts()
    assert t.server > 0 and t.task_poll <= 0.2
    assert t.with_(server=2.5).server == 2.5
    for bad in (math.inf, math.nan, -1, 0):
        with pytest.raises(ValueError, match="server"):
            NavigatorTimeouts(server=bad)
    with pytest.raises(TypeError):
        NavigatorTimeouts(response="10")  # type: ignore[arg-type]
    assert NavigatorTimeouts(clock_discovery=0).clock_discovery == 0


def test_results_and_status_names() -> None:
    assert [r.value for r in TaskResult] == [0, 1, 2, 3]
    assert task_result_of(4) is TaskResult.SUCCEEDED and task_result_of(6) is TaskResult.FAILED
    assert task_result_of(5) is TaskResult.CANCELED and task_result_of(None) is TaskResult.UNKNOWN
    assert status_name(6) == "ABORTED" and status_name(None) == "REJECTED"


def test_numpy_numbers_are_numbers() -> None:
    import numpy as np

    assert check_number(np.float32(1.5), "x") == 1.5 and check_number(np.int64(2), "x") == 2.0
    with pytest.raises(ValueError):
        check_number(np.float64("nan"), "x")
