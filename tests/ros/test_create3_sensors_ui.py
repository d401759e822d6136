"""The Create 3's proprioceptive sensors, its user interface and its services over DDS: wheel ticks (508.8 per
turn), wheel speeds, IMU, mouse, stop/slip status, reset_pose, IR codes of the dock, buttons pressed with
`tb4 press`, the light ring and the speaker (commands and goals, in the run record), robot_power."""

from __future__ import annotations

import json
import math
import time

from geometry_msgs.msg import Pose
from irobot_create_msgs.action import AudioNoteSequence, DriveDistance, LedAnimation, RotateAngle, Undock
from irobot_create_msgs.msg import (
    AudioNote,
    AudioNoteVector,
    InterfaceButtons,
    IrIntensityVector,
    IrOpcode,
    LedColor,
    LightringLeds,
    Mouse,
    SlipStatus,
    StopStatus,
    WheelStatus,
    WheelTicks,
    WheelVels,
)
from irobot_create_msgs.srv import ResetPose, RobotPower
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu

from tb4.core.robot_params import default_robot_params
from tb4.core.waits import wait_for_future
from tb4.processes import tb4_command
from tb4.ros.convert import duration_msg

from .create3_helpers import CANCELED, REJECTED, SUCCEEDED, call, lab_world, odom_xy_yaw

C3 = default_robot_params().create3


def test_wheels_imu_mouse_status_and_reset_pose(start_simulator, ros, tmp_path) -> None:
    start_simulator("--rate", "10", "--world", lab_world(tmp_path), "--exact")
    odom = ros.latest(Odometry, "odom")
    ticks = ros.latest(WheelTicks, "wheel_ticks")
    mouse = ros.latest(Mouse, "mouse")
    cliff = ros.latest(IrIntensityVector, "cliff_intensity")
    # every message of what lasts only while a goal runs: at 10x a 0.5 m drive or a 3 rad turn passes in about
    # half a second of wall time, and slip_status (1 Hz of sim time) says "slipping" once or twice
    vels = ros.every(WheelVels, "wheel_vels")
    imu = ros.every(Imu, "imu")
    stop = ros.every(StopStatus, "stop_status")
    slips = ros.every(SlipStatus, "slip_status")
    assert ros.wait_for(stop, bool, what="stop_status")[-1].is_stopped
    assert all(r.value > 1000 for r in ros.wait_for(cliff, what="cliff_intensity").readings)  # floor under all 4
    assert abs(ros.wait_for(imu, bool, what="imu")[-1].linear_acceleration.z - 9.81) < 0.01
    t0, m0 = ros.wait_for(ticks, what="wheel_ticks"), ros.wait_for(mouse, what="mouse")

    stop().clear()
    vels().clear()
    handle = ros.send_goal(DriveDistance, "drive_distance", DriveDistance.Goal(distance=0.5, max_translation_speed=0.1))
    ros.first(stop, lambda m: not m.is_stopped, what="stop_status while driving")
    cruise = 0.1 / C3.wheel_radius  # rad/s at 0.1 m/s, once the ramp is over
    v = ros.first(vels, lambda m: abs(m.velocity_left - cruise) < 0.05, what="wheels at cruise speed")
    assert abs(v.velocity_right - v.velocity_left) < 1e-3  # straight: both wheels alike
    assert wait_for_future(handle.get_result_async(), 30.0, "drive").status == SUCCEEDED
    expected = 0.5 / (2 * math.pi * C3.wheel_radius) * C3.ticks_per_rev  # 1132.6 ticks
    t1 = ros.wait_for(
        ticks,
        lambda m: abs((m.ticks_left - t0.ticks_left) - expected) < 0.01 * expected,
        what=f"{expected:.0f} ticks (1 %) after 0.5 m",
    )
    assert abs((t1.ticks_right - t0.ticks_right) - expected) < 0.01 * expected
    ros.wait_for(mouse, lambda m: abs((m.integrated_x - m0.integrated_x) - 0.5) < 0.01, what="mouse: 0.5 m (1 cm)")

    # Turning left in place: the gyro reads the rate, the wheels turn opposite ways.
    imu().clear()
    vels().clear()  # the drive's ramp passed through the turn's wheel speed, both wheels alike
    handle = ros.send_goal(RotateAngle, "rotate_angle", RotateAngle.Goal(angle=3.0, max_rotation_speed=0.5))
    ros.first(imu, lambda m: m.angular_velocity.z > 0.45, what="gyro while turning")
    spin = 0.5 * C3.wheel_base / 2 / C3.wheel_radius  # rad/s of each wheel turning at 0.5 rad/s
    w = ros.first(vels, lambda m: abs(m.velocity_right - spin) < 0.1, what="wheels while turning")
    assert abs(w.velocity_left + w.velocity_right) < 1e-3  # in place: opposite ways
    assert wait_for_future(handle.get_result_async(), 30.0, "rotate").status == SUCCEEDED
    assert max(m.angular_velocity.z for m in imu()) < 0.55  # never much over the goal's limit

    # Pushing a wall: the wheels slip (and stall), then the goal aborts.
    assert ros.action(RotateAngle, "rotate_angle", RotateAngle.Goal(angle=-3.0))[0] == SUCCEEDED
    slips().clear()
    handle = ros.send_goal(DriveDistance, "drive_distance", DriveDistance.Goal(distance=3.0))
    ros.first(slips, lambda m: m.is_slipping, timeout=30, what="slip_status against the wall")
    wait_for_future(handle.get_result_async(), 30.0, "drive into the wall")

    # reset_pose: odometry reads the given pose from now on.
    request = ResetPose.Request(pose=Pose())
    request.pose.position.x, request.pose.position.y = 1.0, 2.0
    request.pose.orientation.z, request.pose.orientation.w = math.sin(0.25), math.cos(0.25)
    call(ros, ResetPose, "reset_pose", request)
    x, y, yaw = odom_xy_yaw(ros.wait_for(odom, lambda m: abs(m.pose.pose.position.x - 1.0) < 1e-3, what="reset"))
    assert abs(y - 2.0) < 1e-3 and abs(yaw - 0.5) < 1e-3
    bad = ResetPose.Request(pose=Pose())
    bad.pose.position.x = float("nan")
    call(ros, ResetPose, "reset_pose", bad)  # refused with a warning; odometry unchanged
    time.sleep(0.3)
    assert abs(odom_xy_yaw(ros.wait_for(odom))[0] - 1.0) < 1e-3


def _colors(msg) -> list[tuple[int, int, int]]:
    return [(c.red, c.green, c.blue) for c in msg.leds]


def test_buttons_lightring_audio_dock_codes_and_power(start_simulator, start_process, ros, tmp_path) -> None:
    record = tmp_path / "run.json"
    sim = start_simulator("--rate", "5", "--world", "depot", "--record-run", str(record))
    buttons: list = []
    ros.node.create_subscription(InterfaceButtons, "interface_buttons", buttons.append, 10)
    ring: list = []
    ros.node.create_subscription(LightringLeds, "tb4_sim/lightring", ring.append, 10)
    codes: list = []
    ros.node.create_subscription(IrOpcode, "ir_opcode", codes.append, 10)
    wheels = ros.latest(WheelStatus, "wheel_status")

    # Docked: the dock's force field and both buoys are received.
    ros.wait_for(lambda: codes, lambda c: {m.opcode for m in c} >= {161, 172}, what="dock IR codes")

    # A person presses button 1 for half a second: pressed, then released with the duration.
    proc = start_process(tb4_command("press", "1", "--hold", "0.5"), name="press")
    assert proc.popen.wait(30) == 0, proc.output()
    ros.wait_for(lambda: buttons, lambda b: any(m.button_1.is_pressed for m in b), what="button_1 pressed")
    released = ros.wait_for(
        lambda: buttons, lambda b: b and b[-1].button_1.last_pressed_duration.nanosec > 0, what="button_1 released"
    )[-1]
    assert not released.button_1.is_pressed and not released.button_2.is_pressed
    assert abs(released.button_1.last_pressed_duration.nanosec * 1e-9 - 0.5) < 0.06

    # cmd_lightring overrides the ring; an empty message hands it back to the robot (white).
    cmd = ros.node.create_publisher(LightringLeds, "cmd_lightring", 10)
    red = LightringLeds(override_system=True, leds=[LedColor(red=255)] * 6)
    ros.wait_for(lambda: cmd.get_subscription_count(), what="cmd_lightring subscriber")

    def shows(msg, colour):  # cmd_lightring is best effort, as on the robot: repeat until it shows
        def check(r) -> bool:
            if r and _colors(r[-1]) == [colour] * 6:
                return True
            cmd.publish(msg)
            time.sleep(0.1)
            return False

        return check

    ros.wait_for(lambda: ring, shows(red, (255, 0, 0)), what="red ring")
    ros.wait_for(lambda: ring, shows(LightringLeds(), (255, 255, 255)), what="ring back to white")

    # led_animation: blink green for 2 s, then the ring is white again.
    goal = LedAnimation.Goal(animation_type=1, max_runtime=duration_msg(2.0))
    goal.lightring = LightringLeds(override_system=True, leds=[LedColor(green=255)] * 6)
    ring.clear()
    status, result = ros.action(LedAnimation, "led_animation", goal)
    assert status == SUCCEEDED and abs(result.runtime.sec + result.runtime.nanosec * 1e-9 - 2.0) < 0.06
    shown = {tuple(_colors(m)) for m in ring}
    assert ((0, 255, 0),) * 6 in shown and ((0, 0, 0),) * 6 in shown  # on and off
    bad = LedAnimation.Goal(animation_type=7, max_runtime=duration_msg(1.0))
    assert ros.action(LedAnimation, "led_animation", bad)[0] == REJECTED

    # audio_note_sequence: two iterations of 0.5 s; an endless one ends only when canceled. tb4_sim/audio (for
    # the viewer) says what sounds.
    sounding: list[int] = []
    ros.node.create_subscription(AudioNote, "tb4_sim/audio", lambda m: sounding.append(m.frequency), 10)
    notes = AudioNoteVector(notes=[AudioNote(frequency=440, max_runtime=duration_msg(0.3)),
                                   AudioNote(frequency=0, max_runtime=duration_msg(0.2))])  # fmt: skip
    status, result = ros.action(AudioNoteSequence, "audio_note_sequence",
                                AudioNoteSequence.Goal(iterations=2, note_sequence=notes))  # fmt: skip
    assert status == SUCCEEDED and result.complete and result.iterations_played == 2
    assert abs(result.runtime.sec + result.runtime.nanosec * 1e-9 - 1.0) < 0.06
    assert 440 in sounding and sounding[-1] == 0  # played, then silent
    endless = ros.send_goal(AudioNoteSequence, "audio_note_sequence",
                            AudioNoteSequence.Goal(iterations=-1, note_sequence=notes))  # fmt: skip
    time.sleep(0.5)
    wait_for_future(endless.cancel_goal_async(), 10.0, "cancel audio")
    response = wait_for_future(endless.get_result_async(), 10.0, "canceled audio")
    assert response.status == CANCELED and not response.result.complete
    for bad_goal in (AudioNoteSequence.Goal(iterations=0, note_sequence=notes), AudioNoteSequence.Goal(iterations=1)):
        assert ros.action(AudioNoteSequence, "audio_note_sequence", bad_goal)[0] == REJECTED
    audio = ros.node.create_publisher(AudioNoteVector, "cmd_audio", 10)
    ros.wait_for(lambda: audio.get_subscription_count(), what="cmd_audio subscriber")
    audio.publish(AudioNoteVector(notes=[AudioNote(frequency=392, max_runtime=duration_msg(0.2))]))

    # robot_power off the dock: wheels disabled, goals refused; put back on the dock, it wakes up.
    assert ros.action(Undock, "undock", Undock.Goal())[0] == SUCCEEDED
    response = call(ros, RobotPower, "robot_power", RobotPower.Request())
    assert response.success
    assert not ros.wait_for(wheels, lambda m: not m.wheels_enabled, what="wheels off").wheels_enabled
    assert ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=0.2))[0] == REJECTED
    proc = start_process(tb4_command("kidnap", "0", "0", "0"), name="kidnap")
    assert proc.popen.wait(30) == 0, proc.output()
    ros.wait_for(wheels, lambda m: m.wheels_enabled, timeout=30, what="woken up on the dock")

    assert sim.stop() == 0
    events = json.loads(record.read_text())["events"]
    kinds = {e["type"] for e in events}
    assert {"button", "lightring", "audio", "robot_power", "kidnap"} <= kinds, kinds
    assert any(e["type"] == "audio" and e["notes"] == [[392, 0.2]] for e in events)
    assert any(e["type"] == "lightring" and e["override"] and e["leds"][0] == [255, 0, 0] for e in events)
