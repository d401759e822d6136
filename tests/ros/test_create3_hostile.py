"""Hostile input to the Create 3 surface: floods of goals, NaN and out-of-bounds person inputs, bad notes. Each
is refused with a reason in the log or handled as the robot would, and the simulator keeps serving."""

from __future__ import annotations

import math
import time

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped
from irobot_create_msgs.action import RotateAngle
from irobot_create_msgs.msg import AudioNote, AudioNoteVector, Button, KidnapStatus
from irobot_create_msgs.srv import EStop
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from tb4.core.waits import wait_for_future

from .create3_helpers import ABORTED, SUCCEEDED, call, lab_world, odom_xy_yaw


def _publisher(ros, msg_type, topic: str):
    pub = ros.node.create_publisher(msg_type, topic, 10)
    ros.wait_for(lambda: pub.get_subscription_count(), what=f"a subscriber on {topic}")
    time.sleep(0.5)  # let the subscriber match this writer too (reliable: then nothing is dropped)
    return pub


def _pose(x: float, y: float, frame: str = "map") -> PoseStamped:
    p = PoseStamped()
    p.header.frame_id = frame
    p.pose.position.x, p.pose.position.y = x, y
    p.pose.orientation.w = 1.0
    return p


def test_floods_and_bad_person_inputs_leave_the_simulator_serving(start_simulator, ros, tmp_path) -> None:
    sim = start_simulator("--rate", "5", "--world", lab_world(tmp_path), "--exact")
    odom = ros.latest(Odometry, "odom")
    scan = ros.latest(LaserScan, "scan")
    kidnapped: list[bool] = []
    ros.node.create_subscription(KidnapStatus, "kidnap_status", lambda m: kidnapped.append(m.is_kidnapped), 10)
    ros.wait_for(odom, what="odom")

    # 20 goals of a full turn as fast as they can be sent: each preempts the previous one (all aborted), the
    # last one turns its full turn. Turning in place, so the flood cannot drive the robot into anything. Slowly
    # (12 sim s, 2.4 s wall each): a goal acknowledged late on a loaded machine must not finish before the next.
    flood = [RotateAngle.Goal(angle=6.0 + 0.01 * i, max_rotation_speed=0.5) for i in range(20)]
    handles = [ros.send_goal(RotateAngle, "rotate_angle", goal) for goal in flood]
    statuses = [wait_for_future(h.get_result_async(), 60.0, "flooded goal").status for h in handles]
    assert statuses == [ABORTED] * 19 + [SUCCEEDED], (statuses, sim.output()[-3000:])
    time.sleep(0.5)
    before = list(ros.wait_for(scan, what="scan").ranges)

    # Person inputs that make no sense are refused; the robot stays where it is.
    kidnap = _publisher(ros, PoseStamped, "tb4_sim/kidnap")
    for bad in (_pose(math.nan, 0.0), _pose(-3.9, -1.0), _pose(-6.0, -1.0, "odom"), _pose(1e9, 0.0)):
        kidnap.publish(bad)
    press = _publisher(ros, Button, "tb4_sim/press_button")
    for name, hold in (("button_9", 0.2), ("button_1", 1e9), ("", 0.2)):
        msg = Button(last_pressed_duration=Duration(sec=int(min(hold, 2**31 - 1))))
        msg.header.frame_id = name
        press.publish(msg)
    audio = _publisher(ros, AudioNoteVector, "cmd_audio")
    audio.publish(AudioNoteVector(notes=[AudioNote(frequency=440, max_runtime=Duration(sec=-5))]))
    audio.publish(AudioNoteVector(notes=[AudioNote(frequency=65535, max_runtime=Duration(nanosec=1))] * 5000))
    for on in [True, False] * 20:  # e-stop hammered: it ends released
        call(ros, EStop, "e_stop", EStop.Request(e_stop_on=on))
    time.sleep(1.0)
    out = sim.output()
    assert "kidnap refused" in out and "no room" in out and "map frame" in out
    assert "press refused" in out and "unknown button" in out and "press duration" in out
    assert "cmd_audio refused" in out
    assert True not in kidnapped
    # nothing moved the robot: the lidar sees exactly what it saw before
    after = list(ros.wait_for(scan).ranges)
    assert max(abs(a - b) for a, b in zip(before, after, strict=True) if math.isfinite(a)) < 1e-4
    status, _ = ros.action(RotateAngle, "rotate_angle", RotateAngle.Goal(angle=1.0))
    assert status == SUCCEEDED and sim.alive()
    x, y, _ = odom_xy_yaw(ros.wait_for(odom))
    assert math.isfinite(x) and math.isfinite(y)
