"""nav2_simple_commander.utils, ours: euler_to_quaternion against rotation facts, the process helpers on a child
process of this test only (never by a name another process could have), and the GPS/behaviour argument checks."""

from __future__ import annotations

import math
import subprocess
import sys
import uuid

import numpy as np
import pytest

pytest.importorskip("geographic_msgs.msg", reason="interface packages not built")

from geographic_msgs.msg import GeoPose  # noqa: E402

from tb4.navigator._goals import check_geo_poses, seconds_msg  # noqa: E402
from tb4.navigator.utils import euler_to_quaternion, find_os_processes, kill_os_processes, kill_process  # noqa: E402


def _rotate(q, v):  # type: ignore[no-untyped-def]
    w, x, y, z = q.w, q.x, q.y, q.z
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    return r @ np.asarray(v, dtype=float)


def test_euler_to_quaternion_yaw_and_composition() -> None:
    q = euler_to_quaternion()
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    q = euler_to_quaternion(yaw=math.pi / 2)
    assert np.allclose(_rotate(q, [1, 0, 0]), [0, 1, 0])  # +x turns to +y: counter-clockwise
    q = euler_to_quaternion(0.0, 0.0, -math.pi)
    assert np.allclose(_rotate(q, [1, 0, 0]), [-1, 0, 0])
    # Z-Y-X order: roll about x first, then pitch about y, then yaw about z.
    roll, pitch, yaw = 0.3, -0.7, 2.1
    q = euler_to_quaternion(roll, pitch, yaw)
    assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0)
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    for v in ([1, 0, 0], [0, 1, 0], [0, 0, 1]):
        assert np.allclose(_rotate(q, v), rz @ ry @ rx @ np.asarray(v, dtype=float))


@pytest.mark.parametrize("bad", [math.nan, math.inf, "1.0", None])
def test_euler_to_quaternion_rejects_bad_angles(bad: object) -> None:
    with pytest.raises((TypeError, ValueError)):
        euler_to_quaternion(yaw=bad)  # type: ignore[arg-type]


def test_process_helpers_on_our_own_child(capsys: pytest.CaptureFixture) -> None:
    tag = f"tb4_utils_test_{uuid.uuid4().hex}"
    child = subprocess.Popen([sys.executable, "-c", "import time, sys; time.sleep(60)", tag])
    try:
        found = find_os_processes(sys.executable)
        mine = [(pid, cmd) for pid, cmd in found if pid == str(child.pid)]
        assert mine and tag in mine[0][1]
        kill_process(str(child.pid))
        assert child.wait(timeout=10) == -9
        assert f"Successfully killed process with PID: {child.pid}" in capsys.readouterr().out
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(timeout=10)
    kill_process("not-a-pid")
    assert "Failed to kill process with PID: not-a-pid" in capsys.readouterr().out
    kill_os_processes(f"/nonexistent/{tag}")
    assert f"No processes found starting with /nonexistent/{tag}" in capsys.readouterr().out
    with pytest.raises(ValueError):
        find_os_processes("")


def geo(lat: float, lon: float, alt: float = 0.0) -> GeoPose:
    g = GeoPose()
    g.position.latitude, g.position.longitude, g.position.altitude = lat, lon, alt
    g.orientation.w = 1.0
    return g


def test_geo_pose_checks() -> None:
    assert len(check_geo_poses([geo(90.0, -180.0), geo(-90.0, 180.0, math.nan)])) == 2
    for bad, match in (
        ([geo(math.nan, 0.0)], "latitude"),
        ([geo(-90.5, 0.0)], "latitude"),
        ([geo(0.0, 180.01)], "longitude"),
        ([geo(0.0, 0.0, -math.inf)], "altitude"),
        ((), "list|empty"),
        ("lat,lon", "list"),
    ):
        with pytest.raises((TypeError, ValueError), match=match):
            check_geo_poses(bad)
    spinning = geo(0.0, 0.0)
    spinning.orientation.x = math.nan
    with pytest.raises(ValueError, match="quaternion"):
        check_geo_poses([spinning])


def test_time_allowance_seconds() -> None:
    assert (seconds_msg(10, "t").sec, seconds_msg(10, "t").nanosec) == (10, 0)
    d = seconds_msg(2.5, "t")
    assert (d.sec, d.nanosec) == (2, 500_000_000)
    for bad in (0, -1, math.inf, math.nan, 2**40, True):
        with pytest.raises((TypeError, ValueError)):
            seconds_msg(bad, "time_allowance")
