"""The Create 3 base in the core (no ROS): hazards, safety, sensors, drive goals and person inputs."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tb4.config import ConfigError
from tb4.core.robot_params import default_robot_params, load_robot_params
from tb4.sim.hazards import BACKUP_LIMIT, BUMP, CLIFF, STALL, WHEEL_DROP, BackupLimit, bump_frame
from tb4.sim.motion import DriveArc, DriveDistance, NavigateToPosition, RotateAngle, WallFollow
from tb4.sim.simulation import Simulation
from tb4.sim.ui import AudioSequence, LedAnimation, Note
from tb4.sim.world import WORLDS_DIR, load_world

P = default_robot_params()
WORLD = f"""
name: lab
map: {WORLDS_DIR / "depot_map.yaml"}
dock: [0.0, 0.0, 0.0]
start: [-6.0, -1.0, 0]
obstacles:
  - {{shape: box, position: [-3.9, -1.0], size: [0.2, 1.6], heading: 0}}
  - {{shape: box, position: [-6.0, 1.0], size: [6.0, 0.2], heading: 0}}
cliffs:
  - {{shape: box, position: [-9.0, -1.0], size: [1.0, 3.0]}}
"""


@pytest.fixture
def sim(tmp_path: Path) -> Simulation:
    path = tmp_path / "lab.yaml"
    path.write_text(WORLD)
    return Simulation.from_world(load_world(path))


def odom(sim: Simulation):
    return lambda: (sim.odometry().x, sim.odometry().y, sim.odometry().yaw)


def run(sim: Simulation, state, limit: float = 60.0) -> None:
    steps = int(limit / sim.physics_dt)
    while not state.done and steps:
        sim.step()
        steps -= 1
    assert state.done, f"{state} still running after {limit} s"


def types(sim: Simulation) -> set[tuple[int, str]]:
    return {(h.type, h.frame) for h in sim.base.hazards()}


@pytest.mark.parametrize(
    ("deg", "frame"),
    [(0, "bump_front_center"), (30, "bump_front_left"), (-30, "bump_front_right"), (80, "bump_left"),
     (-80, "bump_right"), (170, "bump_left"), (-170, "bump_right")],
)  # fmt: skip
def test_bumper_zones(deg: float, frame: str) -> None:
    assert bump_frame(math.radians(deg)) == frame


def test_backup_allowance_grows_forward_and_kidnap_empties_it() -> None:
    b = BackupLimit(P.create3)
    b.travel(-0.45)
    assert b.reported and b.allows(-0.1)
    b.travel(-0.1)
    assert b.stopped and not b.allows(-0.1) and b.allows(0.1)
    b.travel(0.05)
    assert b.stopped  # forward a little is not enough
    b.travel(0.2)
    assert not b.stopped and not b.reported
    b.kidnapped()
    assert not b.allows(-0.01)


def test_drive_goals_reach_their_targets(sim: Simulation) -> None:
    o = odom(sim)
    state = sim.start_motion(lambda: RotateAngle(o, P.drive, math.pi / 2, 1.9))
    run(sim, state)
    assert state.status == "succeeded" and abs(sim.yaw - math.pi / 2) < math.radians(1)
    state = sim.start_motion(lambda: DriveDistance(o, P.drive, 0.5, 0.3))
    run(sim, state)
    assert abs(sim.y - (-0.5)) < 0.005 and abs(sim.x - (-6.0)) < 0.005
    state = sim.start_motion(lambda: DriveArc(o, P.drive, -1, -math.pi / 2, 0.3, 0.2))
    run(sim, state)
    assert state.status == "succeeded" and abs(math.remainder(sim.yaw, 2 * math.pi)) < math.radians(1)
    goal = (o()[0] - 0.6, o()[1] + 0.4, 1.0)
    state = sim.start_motion(lambda: NavigateToPosition(o, P.drive, goal, True, 0.3, 1.9))
    run(sim, state)
    x, y, yaw = o()
    assert math.hypot(x - goal[0], y - goal[1]) < 0.01 and abs(yaw - 1.0) < math.radians(1)


@pytest.mark.parametrize(
    "make",
    [
        lambda o: DriveDistance(o, P.drive, float("nan"), 0.3),
        lambda o: DriveDistance(o, P.drive, 1.0, -0.3),
        lambda o: DriveDistance(o, P.drive, 1.0, float("inf")),
        lambda o: DriveDistance(o, P.drive, 1e9, 0.3),
        lambda o: DriveDistance(o, P.drive, "far", 0.3),
        lambda o: RotateAngle(o, P.drive, 1.0, 0.0),
        lambda o: DriveArc(o, P.drive, 2, 1.0, 0.5, 0.3),
        lambda o: DriveArc(o, P.drive, 1, 1.0, -0.5, 0.3),
        lambda o: NavigateToPosition(o, P.drive, (1e7, 0.0, 0.0), False, 0.3, 1.9),
        lambda o: NavigateToPosition(o, P.drive, (1.0, float("nan"), 0.0), False, 0.3, 1.9),
        lambda o: WallFollow(o, P.drive, 0, 5.0, 0.0, lambda: (1.0, 1.0, 1.0), lambda: False),
        lambda o: WallFollow(o, P.drive, 1, -5.0, 0.0, lambda: (1.0, 1.0, 1.0), lambda: False),
    ],
)
def test_bad_goals_raise_with_a_reason(sim: Simulation, make) -> None:
    with pytest.raises(ValueError):
        sim.start_motion(lambda: make(odom(sim)))
    assert sim._action is None


@pytest.mark.parametrize(("side", "start_yaw"), [(1, 0.0), (-1, math.pi)])
def test_wall_follow_keeps_close_to_the_wall(sim: Simulation, side: int, start_yaw: float) -> None:
    sim.set_pose(-6.0, 0.6, start_yaw)
    state = sim.start_motion(
        lambda: WallFollow(
            odom(sim), P.drive, side, 10.0, sim.time, lambda: sim.base.side_ranges(sim, side), lambda: sim.in_contact
        )
    )
    x0, gaps = sim.x, []
    while not state.done:
        sim.step()
        gaps.append(0.9 - P.drive.radius - sim.y)
    assert state.status == "succeeded" and state.result()["runtime"] == pytest.approx(10.0)
    assert state.fields["engaged"] is True
    assert abs(sim.x - x0) > 1.5  # it went along the wall
    assert max(gaps[300:]) < 0.12 and min(gaps) >= 0.0  # close to it, never into it


def test_bump_stall_abort_and_ir(sim: Simulation) -> None:
    o = odom(sim)
    assert sim.base.ir(sim) == [0] * 7
    state = sim.start_motion(lambda: DriveDistance(o, P.drive, 3.0, 0.3))
    seen: set = set()
    steps = 0
    while not state.done and steps < 6000:
        sim.step()
        steps += 1
        seen |= types(sim)
    assert state.status == "failed" and "stalled" in state.reason
    assert {(BUMP, "bump_front_center"), (STALL, "base_link")} <= seen
    ir = sim.base.ir(sim)
    assert ir[3] > 3000 and ir[3] > ir[0] and ir[3] > ir[6]


def test_preemption_e_stop_and_refusals(sim: Simulation) -> None:
    o = odom(sim)
    first = sim.start_motion(lambda: DriveDistance(o, P.drive, 1.0, 0.3))
    sim.step(50)
    second = sim.start_motion(lambda: RotateAngle(o, P.drive, 1.0, 1.0))
    assert first.status == "failed" and "preempted" in first.reason
    sim.step(20)
    sim.base.estop = True
    sim.stop_motion("e-stop engaged")
    assert second.status == "failed" and sim.velocity() == (0.0, 0.0)
    with pytest.raises(ValueError, match="e-stop"):
        sim.start_motion(lambda: DriveDistance(o, P.drive, 1.0, 0.3))
    assert sim.set_velocity_command(0.2, 0.0)[0] is False


def test_cliff_stops_before_the_edge_and_full_override_drops_a_wheel(sim: Simulation) -> None:
    o = odom(sim)
    run(sim, sim.start_motion(lambda: RotateAngle(o, P.drive, math.pi, 1.9)))
    state = sim.start_motion(lambda: DriveDistance(o, P.drive, 4.0, 0.3))
    run(sim, state)
    assert state.status == "failed" and "cliff" in state.reason
    assert {(CLIFF, "cliff_front_left"), (CLIFF, "cliff_front_right")} <= types(sim)
    assert -8.5 < sim.x < -8.5 + 0.175
    sim.base.set_safety_override("full")
    for _ in range(300):
        sim.set_velocity_command(0.1, 0.0)
        sim.step()
    assert (WHEEL_DROP, "wheel_drop_left") in types(sim)
    assert sim.set_velocity_command(0.1, 0.0)[0] is False
    with pytest.raises(ValueError):
        sim.base.set_safety_override("fulll")


def test_backup_limit_brakes_cmd_vel_reversing(sim: Simulation) -> None:
    x0 = sim.x
    for _ in range(600):
        sim.set_velocity_command(-0.2, 0.0)
        sim.step()
    assert (BACKUP_LIMIT, "base_link") in types(sim)
    assert abs((x0 - sim.x) - P.create3.backup_limit) < 0.02


def test_kidnap_lifts_then_places_and_only_the_heading_follows(sim: Simulation) -> None:
    before = sim.odometry()
    with pytest.raises(ValueError, match="no room"):
        sim.kidnap(-3.9, -1.0, 0.0)  # inside the wall
    sim.kidnap(-6.0, 0.3, math.pi / 2)
    sim.step(10)
    assert sim.base.lifted and (WHEEL_DROP, "wheel_drop_left") in types(sim)
    assert sim.base.ir(sim) == [0] * 7
    sim.step(int(P.create3.kidnap_lift_time / sim.physics_dt))
    assert not sim.base.lifted and (sim.x, sim.y) == (-6.0, 0.3)
    after = sim.odometry()
    assert (after.x, after.y) == (before.x, before.y)  # nothing rolled: the position does not jump
    assert after.yaw == pytest.approx(before.yaw + math.pi / 2)  # the gyro saw the quarter turn
    assert sim.base.proprio.mouse_frame == 1


def test_wheel_ticks_and_buttons(sim: Simulation) -> None:
    o = odom(sim)
    run(sim, sim.start_motion(lambda: DriveDistance(o, P.drive, 1.0, 0.3)))
    left, right = sim.base.proprio.ticks
    expected = 1.0 / (2 * math.pi * P.create3.wheel_radius) * P.create3.ticks_per_rev
    assert abs(left - expected) < 0.005 * expected and abs(right - expected) < 0.005 * expected
    sim.base.press("button_1", 0.3, sim.time)
    assert sim.base.buttons["button_1"].is_pressed
    sim.step(31)
    b = sim.base.buttons["button_1"]
    assert not b.is_pressed and abs(b.last_duration - 0.3) < 1e-9
    with pytest.raises(ValueError):
        sim.base.press("button_3", 0.3, sim.time)
    with pytest.raises(ValueError):
        sim.base.press("button_1", float("nan"), sim.time)


def test_led_and_audio_goals() -> None:
    with pytest.raises(ValueError):
        LedAnimation(3, [(0, 0, 0)] * 6, 1.0, 0.0)
    with pytest.raises(ValueError):
        LedAnimation(1, [(0, 0, 0)] * 5, 1.0, 0.0)
    blink = LedAnimation(1, [(0, 255, 0)] * 6, 2.0, 0.0)
    assert blink.frame(0.1) == ((0, 255, 0),) * 6 and blink.frame(0.6) == ((0, 0, 0),) * 6
    blink.step(2.0)
    assert blink.status == "succeeded" and blink.result()["runtime"] == 2.0
    with pytest.raises(ValueError):
        AudioSequence([Note(440, 0.0)], 1, 0.0)
    with pytest.raises(ValueError):
        AudioSequence([Note(440, float("nan"))], 1, 0.0)
    seq = AudioSequence([Note(440, 0.3), Note(0, 0.2)], 3, 0.0)
    seq.step(1.2)
    assert seq.feedback()["iterations_played"] == 2 and seq.note_at(1.1) == 440 and seq.note_at(1.4) == 0
    seq.step(1.5)
    assert seq.result() == {"complete": True, "iterations_played": 3, "runtime": 1.5}


def test_world_and_params_validation(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(WORLD.replace("position: [-9.0, -1.0], size: [1.0, 3.0]", "path: [[0, 0], [1, 1]], speed: 1"))
    with pytest.raises(ConfigError, match="cliffs"):
        load_world(bad)
    with pytest.raises(ConfigError, match="create3.ir_angles"):
        load_robot_params(overrides={"create3": {"ir_angles": "left"}})
    with pytest.raises(ConfigError, match=r"create3.cliff_angles\[1\]"):
        load_robot_params(overrides={"create3": {"cliff_angles": [10, "x"]}})
    assert load_world("depot").cliffs  # the depot has its loading-dock edge
