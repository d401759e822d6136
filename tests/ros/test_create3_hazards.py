"""Create 3 hazards over DDS with rclpy's default subscription profile: bumps at the touching side, a stall that
aborts the drive, IR intensities that rise near a wall, the backup limit and safety_override, cliffs that stop
the robot before the edge, wheel drops when the safety is off, and kidnap_status."""

from __future__ import annotations

import math
import time

from geometry_msgs.msg import Twist, Vector3
from irobot_create_msgs.action import DriveDistance, RotateAngle
from irobot_create_msgs.msg import HazardDetectionVector, IrIntensityVector, KidnapStatus, WheelStatus
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.qos import QoSProfile
from sensor_msgs.msg import LaserScan

from tb4.processes import tb4_command

from .create3_helpers import ABORTED, SUCCEEDED, call, hazards, lab_world, odom_xy_yaw

BACKUP_LIMIT, BUMP, CLIFF, STALL, WHEEL_DROP = 0, 1, 2, 3, 4


class HazardLog:
    """Every hazard (type, frame) seen on hazard_detection since the last clear()."""

    def __init__(self, ros) -> None:
        self.seen: set[tuple[int, str]] = set()
        self.stamped: list[tuple[float, int, str]] = []  # (sim time, type, frame) of every detection received
        self.latest = None
        # a deep queue: a hazard lasting a few ticks must not be overwritten while this process is busy
        ros.node.create_subscription(HazardDetectionVector, "hazard_detection", self._on, QoSProfile(depth=1000))

    def _on(self, msg) -> None:
        self.latest = msg
        self.seen |= hazards(msg)
        stamp = _seconds(msg.header.stamp)
        self.stamped.extend((stamp, t, f) for t, f in hazards(msg))

    def clear(self) -> None:
        self.seen = set()

    def wait_seen(self, ros, wanted: set[tuple[int, str]], what: str) -> None:
        """The result of a goal can arrive before the hazard message of the same tick: wait (bounded)."""
        ros.wait_for(lambda: self.seen, lambda seen: wanted <= seen, timeout=10.0, what=what)


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _at_rest(ros, odom):
    """Odometry once the robot stands still: a message taken right after a result may predate the stop."""
    msg = ros.wait_for(
        odom, lambda m: abs(m.twist.twist.linear.x) < 1e-4 and abs(m.twist.twist.angular.z) < 1e-4, what="at rest"
    )
    return odom_xy_yaw(msg)


def _set_override(ros, value: str) -> bool:
    request = SetParameters.Request()
    param = Parameter(name="safety_override")
    param.value = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
    request.parameters = [param]
    return call(ros, SetParameters, "motion_control/set_parameters", request).results[0].successful


def _drive_with_cmd_vel(ros, v: float, seconds: float) -> None:
    # one publisher per client, never destroyed: destroying one while the client's executor waits on it kills
    # the executor's thread (rclpy InvalidHandle)
    cmd = getattr(ros, "cmd_vel_publisher", None)
    if cmd is None:
        cmd = ros.cmd_vel_publisher = ros.node.create_publisher(Twist, "cmd_vel", 10)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        cmd.publish(Twist(linear=Vector3(x=v)))
        time.sleep(0.05)


def test_bumps_stall_ir_and_backup_limit(start_simulator, ros, tmp_path) -> None:
    sim = start_simulator("--rate", "10", "--world", lab_world(tmp_path), "--exact")
    log = HazardLog(ros)
    odom = ros.latest(Odometry, "odom")
    ir = ros.latest(IrIntensityVector, "ir_intensity")
    start = odom_xy_yaw(ros.wait_for(odom, what="odom"))
    ros.wait_for(lambda: log.latest, what="hazard_detection")
    assert hazards(log.latest) == set()  # nothing detected in open space
    assert max(r.value for r in ros.wait_for(ir, what="ir_intensity").readings) == 0

    # Drive 3 m at a wall 2 m ahead: the bumper touches in the front centre, the wheels stall, the goal aborts.
    status, result = ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=3.0))
    assert status == ABORTED
    log.wait_seen(ros, {(BUMP, "bump_front_center"), (STALL, "base_link")}, "bump and stall")
    x, y, _ = _at_rest(ros, odom)
    assert abs((x - start[0]) - (2.0 - 0.175)) < 0.03  # stopped with the bumper on the wall's face
    assert abs(result.pose.pose.position.x - x) < 0.01
    touching = [r.value for r in ros.wait_for(ir, lambda m: m.readings[3].value > 3000, what="IR at contact").readings]
    assert [r.header.frame_id for r in ir().readings][3] == "ir_intensity_front_center_left"
    assert touching[3] > touching[0] and touching[3] > touching[6]  # the wall is ahead, not at the sides

    # Back off 10 cm: no bump any more, the front IR reads the wall weaker. Judged on a reading taken once the
    # robot stopped (stamped at or after the result): on a loaded machine the newest reading received when the
    # result arrives can still be one from the way back.
    status, result = ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=-0.1))
    assert status == SUCCEEDED
    stopped = _seconds(result.pose.header.stamp)
    msg = ros.wait_for(ir, lambda m: _seconds(m.header.stamp) >= stopped, what="IR after backing off")
    assert 200 < msg.readings[3].value < 1500
    ros.wait_for(lambda: log.latest, lambda m: (BUMP, "bump_front_center") not in hazards(m), what="bump released")

    # Approach at -30 deg: the wall now touches the front-left of the bumper.
    assert ros.action(RotateAngle, "rotate_angle", RotateAngle.Goal(angle=-math.radians(30)))[0] == SUCCEEDED
    log.clear()
    assert ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=0.5))[0] == ABORTED
    log.wait_seen(ros, {(BUMP, "bump_front_left")}, "bump on the front left")
    assert {f for t, f in log.seen if t == BUMP} == {"bump_front_left"}, log.seen

    # Reverse with cmd_vel: BACKUP_LIMIT is reported, then the robot brakes after ~0.5 m (create3 safety).
    x0, y0, _ = _at_rest(ros, odom)
    log.clear()
    _drive_with_cmd_vel(ros, -0.2, 5.0)
    x1, y1, _ = _at_rest(ros, odom)
    assert (BACKUP_LIMIT, "base_link") in log.seen
    assert 0.4 < math.hypot(x1 - x0, y1 - y0) < 0.56
    assert (BACKUP_LIMIT, "base_link") in hazards(log.latest)
    assert "backup limit" in sim.output() and sim.alive()

    # safety_override: a typo is refused by the parameter service; backup_only lets it reverse further.
    assert not _set_override(ros, "fulll")
    assert _set_override(ros, "backup_only")
    _drive_with_cmd_vel(ros, -0.2, 1.5)
    x2, y2, _ = odom_xy_yaw(ros.wait_for(odom))
    assert math.hypot(x2 - x1, y2 - y1) > 0.15
    ros.wait_for(lambda: log.latest, lambda m: (BACKUP_LIMIT, "base_link") not in hazards(m), what="limit lifted")


def test_cliff_stops_the_robot_before_the_edge_and_kidnap(start_simulator, start_process, ros, tmp_path) -> None:
    start_simulator("--rate", "10", "--world", lab_world(tmp_path), "--exact")
    log = HazardLog(ros)
    odom = ros.latest(Odometry, "odom")
    scan = ros.latest(LaserScan, "scan")
    kidnap = ros.latest(KidnapStatus, "kidnap_status")
    wheels = ros.latest(WheelStatus, "wheel_status")
    seen_kidnapped: list[bool] = []
    ros.node.create_subscription(
        KidnapStatus, "kidnap_status", lambda m: seen_kidnapped.append(m.is_kidnapped), QoSProfile(depth=1000)
    )
    before = odom_xy_yaw(ros.wait_for(odom, what="odom"))
    ahead_before = ros.wait_for(scan, what="scan").ranges[0]
    assert abs(ahead_before - 2.1) < 0.1  # the wall, 2.1 m ahead
    assert not ros.wait_for(kidnap, what="kidnap_status").is_kidnapped

    # A person turns the robot around: kidnap_status goes true then false, odometry turns (the gyro) but its
    # position does not jump (nothing rolled), the lidar sees the other side of the hall.
    proc = start_process(tb4_command("kidnap", "-6", "-1", "180"), name="kidnap")
    assert proc.popen.wait(30) == 0, proc.output()
    ahead_after = ros.wait_for(scan, lambda m: m.ranges[0] > 4.0, what="scan of the other side").ranges[0]
    assert ahead_after > 4.0
    ros.wait_for(lambda: seen_kidnapped, lambda s: True in s and s[-1] is False, what="kidnapped, then put down")
    log.wait_seen(ros, {(WHEEL_DROP, "wheel_drop_left"), (WHEEL_DROP, "wheel_drop_right")}, "lifted wheels")
    after = odom_xy_yaw(ros.wait_for(odom, lambda m: abs(odom_xy_yaw(m)[2]) > 3.0, what="odometry turned"))
    assert math.hypot(after[0] - before[0], after[1] - before[1]) < 1e-3  # nothing rolled
    assert abs(math.remainder(after[2] - before[2] - math.pi, 2 * math.pi)) < 1e-3  # the gyro saw the turn

    # Drive 4 m towards a cliff 2.5 m ahead: the front cliff sensors see it, the goal aborts before the edge.
    placed = ros.wait_for(odom).header.stamp
    log.clear()
    status, _ = ros.action(DriveDistance, "drive_distance", DriveDistance.Goal(distance=4.0))
    assert status == ABORTED
    log.wait_seen(ros, {(CLIFF, "cliff_front_left"), (CLIFF, "cliff_front_right")}, "front cliff sensors")
    since = _seconds(placed)
    assert not any(t == WHEEL_DROP for stamp, t, _ in log.stamped if stamp > since)  # (the lift's may lag in)
    x, y, _ = _at_rest(ros, odom)
    travelled = math.hypot(x - after[0], y - after[1])
    assert 2.5 - 0.175 < travelled < 2.5  # the bumper overhangs the edge, the wheels stay on the floor
    cliff = ros.latest(IrIntensityVector, "cliff_intensity")
    values = {r.header.frame_id: r.value for r in ros.wait_for(cliff, what="cliff_intensity").readings}
    assert values["cliff_front_left"] < 100 and values["cliff_front_right"] < 100

    # cmd_vel forwards is refused by the cliff safety... until safety_override full: the robot drives off the
    # edge, its wheels drop, and it cannot drive any more.
    _drive_with_cmd_vel(ros, 0.1, 1.0)
    x1, y1, _ = _at_rest(ros, odom)
    assert math.hypot(x1 - x, y1 - y) < 0.01
    assert _set_override(ros, "full")
    _drive_with_cmd_vel(ros, 0.1, 3.0)
    ros.wait_for(lambda: log.latest, lambda m: (WHEEL_DROP, "wheel_drop_left") in hazards(m), what="wheel drop")
    assert not ros.wait_for(wheels, lambda m: not m.wheels_enabled, what="wheels disabled").wheels_enabled


def test_bump_and_go_takes_a_contact_stamped_before_its_run_as_old_news() -> None:
    """At --rate max the tutorial's back-off and turn take a few wall milliseconds, and messages of the last contact
    can reach it after its next run has started: it took one for a bump of that run, though the simulator saw none
    (stress run 52). A hazard stamped before the run's start is old news; one stamped after it is the run's bump."""
    from irobot_create_msgs.msg import HazardDetection

    from tb4.tutorials.bump_and_go import BumpAndGo

    def contact(stamp: float, frame: str) -> HazardDetectionVector:
        detection = HazardDetection(type=HazardDetection.BUMP)
        detection.header.stamp.sec, detection.header.stamp.nanosec = int(stamp), int(stamp % 1 * 1e9)
        detection.header.frame_id = frame
        return HazardDetectionVector(detections=[detection])

    robot = BumpAndGo("bump_news")
    try:
        robot._on_hazards(contact(64.5, "bump_front_center"))  # the last run's contact, taken before the run starts
        robot.watch_from(70.0)
        assert robot.take_touch() is None
        robot._on_hazards(contact(66.0, "bump_front_center"))  # the same contact, delivered late
        assert robot.take_touch() is None
        robot._on_hazards(contact(71.5, "bump_left"))  # one of this run: taken, and a later one waits its turn
        robot._on_hazards(contact(72.0, "bump_right"))
        assert robot.take_touch() == "bump_left"
        robot.watch_from(80.0)
        robot._on_hazards(contact(80.0, "bump_right"))
        robot.watch_from(80.0)  # a second look at the same start keeps a bump already taken from it
        assert robot.take_touch() == "bump_right"
    finally:
        robot.close()
