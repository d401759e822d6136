"""Publishers that send the same content again and again keep its serialized bytes and rewrite only the stamp:
what goes on the wire must decode to exactly the message a fresh serialization would carry (CDR's alignment
padding is not part of it: rclpy leaves those bytes as it finds them)."""

from __future__ import annotations

import math
import struct

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.msg import DockStatus
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message

from tb4.ros.convert import StampedSerialization, pose_msg, serialized_header_stamp, set_time, set_yaw

pytestmark = pytest.mark.core


def _carries(data: bytes, expected: object) -> bool:
    """`data` is `expected` on the wire: same length, every field equal, zeros with their sign."""
    got = deserialize_message(data, type(expected))
    return len(data) == len(serialize_message(expected)) and got == expected and repr(got) == repr(expected)


def test_the_stamp_of_a_serialized_message_is_read_without_decoding_it() -> None:
    for msg, seconds in ((Odometry(), 7655.35), (DockStatus(), 0.0), (Odometry(), 2.0**31 - 1.5)):
        msg.header.frame_id = "map"
        set_time(msg.header.stamp, seconds)
        assert serialized_header_stamp(serialize_message(msg)) == pytest.approx(seconds, abs=1e-9)
    with pytest.raises(ValueError):
        serialized_header_stamp(b"\x00\x01\x00\x00")


def _odometry(now: float, x: float, y: float, yaw: float, v: float) -> Odometry:
    """The message as the ground-truth publisher used to fill and send it."""
    msg = Odometry()
    msg.header.frame_id = "map"
    msg.child_frame_id = "base_link"
    set_time(msg.header.stamp, now)
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    set_yaw(msg.pose.pose.orientation, yaw)
    msg.twist.twist.linear.x = v
    return msg


def test_kept_bytes_equal_a_fresh_serialization_whatever_changes() -> None:
    msg = Odometry()
    msg.header.frame_id = "map"
    msg.child_frame_id = "base_link"
    kept = StampedSerialization(msg)
    fills = []

    def publish(now: float, x: float, y: float, yaw: float, v: float) -> bytes:
        def fill(m: Odometry) -> None:
            fills.append(now)
            m.pose.pose.position.x, m.pose.pose.position.y = x, y
            set_yaw(m.pose.pose.orientation, yaw)
            m.twist.twist.linear.x = v

        return kept.serialized(now, struct.pack("4d", x, y, yaw, v), fill)

    steps = [(0.0, 1.0, 2.0, 0.5, 0.0), (0.05, 1.0, 2.0, 0.5, 0.0), (7655.35, 1.0, 2.0, 0.5, 0.0)]
    steps += [(7655.4, 1.1, 2.0, 0.5, 0.2), (7655.45, 1.1, 2.0, 0.5, 0.2), (7655.5, -0.0, 0.0, 0.0, 0.0)]
    steps += [(7655.55, 0.0, 0.0, 0.0, 0.0), (1e9 + 0.123456789, 0.0, 0.0, math.pi, 0.0)]
    for step in steps:
        assert _carries(publish(*step), _odometry(*step)), step
    assert fills == [0.0, 7655.4, 7655.5, 7655.55, 1e9 + 0.123456789]  # -0.0 then 0.0: refilled


def test_kept_amcl_pose_and_dock_status_bytes_equal_fresh_ones() -> None:
    pose = PoseWithCovarianceStamped()
    pose.header.frame_id = "map"
    kept = StampedSerialization(pose)
    covariance = [0.0] * 36
    covariance[0], covariance[7], covariance[35] = 0.01, 0.02, 0.003
    for now in (1.0, 1.5, 2.0):

        def fill(m: PoseWithCovarianceStamped) -> None:
            m.pose.pose = pose_msg(-1.0, 1.0, 0.3)
            m.pose.covariance = covariance

        fresh = PoseWithCovarianceStamped()
        fresh.header.frame_id = "map"
        set_time(fresh.header.stamp, now)
        fill(fresh)
        assert _carries(kept.serialized(now, struct.pack("3d36d", -1.0, 1.0, 0.3, *covariance), fill), fresh)
    dock = StampedSerialization(DockStatus())
    for now, visible, docked in ((0.2, True, True), (0.4, True, True), (0.6, True, False)):

        def fill_dock(m: DockStatus, visible: bool = visible, docked: bool = docked) -> None:
            m.dock_visible, m.is_docked = visible, docked

        fresh_dock = DockStatus(dock_visible=visible, is_docked=docked)
        set_time(fresh_dock.header.stamp, now)
        assert _carries(dock.serialized(now, bytes((visible, docked)), fill_dock), fresh_dock)


@pytest.mark.parametrize(
    "data", [b"\x00\x01\x00\x00", b"\x00\x01\x00\x00" + bytes(8), b"\x00\x01\x00\x00" + b"\xff" * 200]
)
def test_hostile_ground_truth_bytes_are_never_paired(data: bytes) -> None:
    """Anyone on the domain can publish raw bytes on ground_truth: too short for a stamp is refused (the run
    monitor drops it), and a stamp whose pose does not decode never pairs with an estimate, while a real
    message at the same time does."""
    from tb4.runner.localization_error import LocalizationErrorTracker
    from tb4.runner.monitor import truth_pose

    if len(data) < 12:
        with pytest.raises(ValueError):
            serialized_header_stamp(data)
        return
    t = serialized_header_stamp(data)
    assert all(math.isnan(v) for v in truth_pose(data))
    tracker = LocalizationErrorTracker()
    tracker.add_truth_later(t, lambda: truth_pose(data))
    assert tracker.add_estimate(t, 0.0, 0.0, 0.0) is None
    real = Odometry()
    set_time(real.header.stamp, t)
    real.pose.pose.position.x = 1.0
    good = serialize_message(real)
    tracker = LocalizationErrorTracker()
    tracker.add_truth_later(t, lambda: truth_pose(good))
    assert tracker.add_estimate(t, 0.0, 0.0, 0.0) == pytest.approx(1.0)


def test_a_repeat_waits_for_the_wall_period_and_a_change_goes_out_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    from tb4.ros.robot import common

    wall = [100.0]
    monkeypatch.setattr(common.time, "monotonic", lambda: wall[0])
    kept = StampedSerialization(DockStatus())
    throttle = common.Throttle()

    def sent(now: float, visible: bool, docked: bool) -> bool:
        key = bytes((visible, docked))
        if throttle.repeat_too_soon("dock_status", kept.repeats(key)):
            return False
        kept.serialized(now, key, lambda m: (setattr(m, "dock_visible", visible), setattr(m, "is_docked", docked)))
        return True

    assert sent(0.0, True, True)  # the first one
    assert not sent(0.2, True, True)  # the same, within the period: held
    wall[0] += 0.5 * common.SENSOR_WALL_PERIOD
    assert not sent(0.4, True, True)
    assert sent(0.6, True, False)  # a change: at once
    assert not sent(0.8, True, False)
    wall[0] += 1.5 * common.SENSOR_WALL_PERIOD
    assert sent(1.0, True, False)  # the period is over: the repeat goes out, with its new stamp
    assert serialized_header_stamp(kept.serialized(1.0, bytes((True, False)), lambda m: None)) == 1.0


class _FakeRobot:
    """What GroundTruthPublisher reads of the loop: the sim's pose and velocity, the lock, its periodic job."""

    def __init__(self) -> None:
        import threading
        from types import SimpleNamespace

        self.lock = threading.Lock()
        self.x = 0.0
        self.v = 0.0
        self.sim = SimpleNamespace(
            pose=lambda: SimpleNamespace(x=self.x, y=0.0, yaw=0.0), velocity=lambda: (self.v, 0.0)
        )
        self.jobs: list = []

    def every(self, period: float, callback) -> None:
        self.jobs.append((period, callback))

    def on_reset(self, callback) -> None:
        """A world reset never comes here."""


class _FakePublisher:
    def __init__(self) -> None:
        self.sent: list[float] = []

    def get_subscription_count(self) -> int:
        return 1

    def publish(self, data: bytes) -> None:
        self.sent.append(serialized_header_stamp(data))


def test_ground_truth_is_bounded_per_wall_second_yet_the_truth_beside_each_estimate_always_goes_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At --rate max the 20 Hz sim-time samples come hundreds of times a wall second: a moving robot's go out at most
    every MIN_WALL_PERIOD wall s, a still robot's repeats every SENSOR_WALL_PERIOD, and the truth at an estimate's
    stamp whatever the bound."""
    from types import SimpleNamespace

    from tb4.ros import ground_truth
    from tb4.ros.robot import common

    wall = [50.0]
    monkeypatch.setattr(common.time, "monotonic", lambda: wall[0])
    robot, pub = _FakeRobot(), _FakePublisher()
    created: list[tuple] = []
    node = SimpleNamespace(create_publisher=lambda *args: created.append(args) or pub)
    truth = ground_truth.GroundTruthPublisher(node, robot)  # type: ignore[arg-type]
    assert [period for period, _ in robot.jobs] == [ground_truth.GROUND_TRUTH_PERIOD]

    sim_time = [0.0]

    def run(seconds_of_wall: float, samples_per_wall_second: int, moving: bool) -> list[float]:
        """Drive the periodic job as a fast loop would; the stamps sent meanwhile."""
        first = len(pub.sent)
        for _ in range(int(seconds_of_wall * samples_per_wall_second)):
            sim_time[0] += ground_truth.GROUND_TRUTH_PERIOD
            robot.v = 0.2 if moving else 0.0
            robot.x += 0.01 if moving else 0.0
            truth.publish(sim_time[0])
            wall[0] += 1.0 / samples_per_wall_second
        return pub.sent[first:]

    moving = run(1.0, 700, moving=True)  # what a drive at --rate max sent before the bound
    assert 0.9 / common.MIN_WALL_PERIOD <= len(moving) <= 1.0 / common.MIN_WALL_PERIOD + 1, len(moving)
    # the writer keeps that wall second: a reliable reader up to a second behind still gets every truth (stress run
    # s34: with 10, a watcher's truth of an estimate was dropped from the history before it had it)
    ((_, topic, depth),) = created
    assert topic == "ground_truth" and depth >= len(moving) - 1
    still = run(1.0, 700, moving=False)
    assert len(still) <= 1.0 / common.SENSOR_WALL_PERIOD + 2, len(still)  # the first still one is a change

    # the truth at an estimate's stamp goes out at once, even right after a sample
    truth.publish(sim_time[0] + 0.05)
    robot.x += 0.5
    for stamp in (sim_time[0] + 0.06, sim_time[0] + 0.07):
        truth.beside_estimate(stamp)
        assert pub.sent[-1] == pytest.approx(stamp)
    sent = len(pub.sent)
    truth.beside_estimate(sim_time[0] + 0.07)  # the same stamp again: not twice
    assert len(pub.sent) == sent
