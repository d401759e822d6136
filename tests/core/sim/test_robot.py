"""Robot parameters, command validation, arc kinematics, ramps, timeout and odometry."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tb4.config import ConfigError
from tb4.core.geometry import arc_pose, wrap_angle
from tb4.core.robot_params import RobotParams, default_robot_params, load_robot_params
from tb4.sim.robot import DiffDrive, OdometryIntegrator, check_command

pytestmark = pytest.mark.core


def test_defaults_are_the_turtlebot4_figures() -> None:
    p = default_robot_params()
    assert isinstance(p, RobotParams)
    assert p.drive.radius == 0.175
    assert (p.drive.max_linear_speed, p.drive.max_angular_speed) == (0.31, 1.9)
    assert p.drive.command_timeout == 0.5
    assert (p.lidar.beams, p.lidar.range_min, p.lidar.range_max, p.lidar.rate_hz) == (360, 0.15, 12.0, 10.0)
    assert p.battery.capacity_wh == 26.0
    assert p.battery.capacity_ah == pytest.approx(26.0 / 14.4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.drive.radius = 1.0  # type: ignore[misc]


def test_partial_user_file_overrides_only_its_keys(tmp_path) -> None:
    f = tmp_path / "robot.yaml"
    f.write_text("lidar:\n  beams: 720\nbattery:\n  capacity_wh: 30\n")
    p = load_robot_params(f)
    assert p.lidar.beams == 720
    assert p.battery.capacity_wh == 30.0
    assert p.lidar.range_max == 12.0  # untouched default
    assert load_robot_params(overrides={"drive": {"radius": 0.2}}).drive.radius == 0.2


def test_misspelt_key_names_file_key_and_suggestion(tmp_path) -> None:
    f = tmp_path / "robot.yaml"
    f.write_text("drive:\n  max_linear_sped: 0.5\n")
    with pytest.raises(ConfigError) as err:
        load_robot_params(f)
    msg = str(err.value)
    assert str(f) in msg and "drive.max_linear_sped" in msg and "did you mean 'max_linear_speed'" in msg


def test_unknown_section_and_bad_values_are_reported() -> None:
    with pytest.raises(ConfigError, match="did you mean 'lidar'"):
        load_robot_params(overrides={"lidarr": {}})
    with pytest.raises(ConfigError, match="drive.radius"):
        load_robot_params(overrides={"drive": {"radius": -1.0}})
    with pytest.raises(ConfigError, match="lidar.beams"):
        load_robot_params(overrides={"lidar": {"beams": 3.5}})
    with pytest.raises(ConfigError, match="range_min"):
        load_robot_params(overrides={"lidar": {"range_min": 20.0}})
    with pytest.raises(ConfigError, match="expected a mapping"):
        load_robot_params(overrides={"lidar": 5})


@pytest.mark.parametrize(
    ("v", "w", "why"),
    [
        (math.nan, 0.0, "not finite"),
        (0.1, math.inf, "not finite"),
        (np.float64("nan"), 0.0, "not finite"),
        ("fast", 0.0, "not a number"),
        (None, 0.0, "not a number"),
        (0.1, [1.0], "not a number"),
        (True, 0.0, "not a number"),
        (1j, 0.0, "not a number"),
        (1e6, 0.0, "absurd"),
        (0.0, -1e9, "absurd"),
        (10**400, 0.0, "absurd"),
    ],
)
def test_bad_commands_are_rejected_with_a_reason(v: object, w: object, why: str) -> None:
    ok, reason, vc, wc = check_command(v, w, default_robot_params().drive)
    assert not ok
    assert why in reason
    assert (vc, wc) == (0.0, 0.0)


def test_commands_are_clamped_to_hardware_limits() -> None:
    drive = default_robot_params().drive
    assert check_command(1.0, -5.0, drive)[:1] == (True,)
    assert check_command(1.0, -5.0, drive)[2:] == (0.31, -1.9)
    ok, reason, vc, wc = check_command(0.2, 0.5, drive)
    assert ok and reason == "ok" and (vc, wc) == (0.2, 0.5)
    assert check_command(np.float32(0.1), 2, drive)[2:] == (pytest.approx(0.1), 1.9)


def test_arc_pose_matches_closed_form_circle() -> None:
    v, w = 0.2, 0.5
    r = v / w
    x, y, yaw = arc_pose(0.0, 0.0, 0.0, v, w, math.pi / w)  # half a turn: opposite side of the circle
    assert (x, y) == (pytest.approx(0.0, abs=1e-12), pytest.approx(2 * r))
    assert abs(wrap_angle(yaw - math.pi)) < 1e-12
    # composing two half-steps equals one step (exact integration, no step-size error)
    a = arc_pose(1.0, -2.0, 0.3, v, w, 0.7)
    b = arc_pose(*arc_pose(1.0, -2.0, 0.3, v, w, 0.35), v, w, 0.35)
    assert a == pytest.approx(b, abs=1e-12)
    # straight line when not turning
    assert arc_pose(0.0, 0.0, math.pi / 2, 0.3, 0.0, 2.0) == pytest.approx((0.0, 0.6, math.pi / 2), abs=1e-12)


def test_ramps_respect_acceleration_limits() -> None:
    p = default_robot_params().drive
    drive = DiffDrive(p)
    vs = []
    for k in range(60):
        assert drive.command(0.3, -1.5, k * 0.01) == (True, "ok")
        vs.append(drive.update(k * 0.01, 0.01))
    for k, (v, w) in enumerate(vs, start=1):
        assert v == pytest.approx(min(k * 0.01 * p.max_linear_accel, 0.3))
        assert w == pytest.approx(max(-k * 0.01 * p.max_angular_accel, -1.5))


def test_command_expires_after_timeout() -> None:
    drive = DiffDrive(default_robot_params().drive)
    drive.command(0.2, 0.0, 0.0)
    t, v = 0.0, 0.0
    while t < 0.5 - 1e-9:
        v, _ = drive.update(t, 0.01)
        t += 0.01
    assert v == pytest.approx(0.2)
    for _ in range(50):
        v, _ = drive.update(t, 0.01)
        t += 0.01
    assert v == 0.0
    assert drive.target_v == 0.0


def test_odometry_without_noise_is_the_motion_relative_to_start() -> None:
    odom = OdometryIntegrator(default_robot_params().odometry)
    start = (3.0, -1.0, 2.0)
    pose = start
    for k in range(200):
        nxt = arc_pose(*pose, 0.25, 0.4 * math.sin(k / 20), 0.05)
        odom.update(pose, nxt, 0.05)
        pose = nxt
    c, s = math.cos(start[2]), math.sin(start[2])
    dx, dy = pose[0] - start[0], pose[1] - start[1]
    r = odom.reading()
    assert (r.x, r.y) == (pytest.approx(c * dx + s * dy, abs=1e-9), pytest.approx(-s * dx + c * dy, abs=1e-9))
    assert abs(wrap_angle(r.yaw - (pose[2] - start[2]))) < 1e-9
    assert r.v == pytest.approx(0.25, rel=1e-6)


def test_odometry_noise_is_seeded_drift() -> None:
    def run(seed: int) -> tuple[float, float, float]:
        odom = OdometryIntegrator(default_robot_params().odometry, np.random.default_rng(seed))
        pose = (0.0, 0.0, 0.0)
        for _ in range(500):
            nxt = arc_pose(*pose, 0.3, 0.2, 0.05)
            odom.update(pose, nxt, 0.05)
            pose = nxt
        r = odom.reading()
        return (r.x, r.y, r.yaw)

    assert run(1) == run(1)
    assert run(1) != run(2)
    truth = OdometryIntegrator(default_robot_params().odometry)
    assert run(1) != (truth.x, truth.y, truth.yaw)
