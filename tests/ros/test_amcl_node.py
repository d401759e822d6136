"""The amcl node over DDS as third-party code uses it: raw rclpy, rclpy's default QoS where Nav2 tools use it."""

from __future__ import annotations

import itertools
import math
import time

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped, Twist
from nav2_msgs.msg import ParticleCloud
from nav2_msgs.srv import SetInitialPose
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from std_srvs.srv import Empty
from tf2_msgs.msg import TFMessage

from tb4.core.waits import wait_until
from tb4.ros.convert import pose_msg, quaternion_to_yaw

pytestmark = pytest.mark.dds

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def initial_pose(
    x: float, y: float, yaw: float, cov: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "map"
    msg.pose.pose = pose_msg(x, y, yaw)
    c = [0.0] * 36
    c[0], c[7], c[35] = cov
    msg.pose.covariance = c
    return msg


def test_amcl_topics_services_and_ground_truth(start_simulator, ros) -> None:
    start_simulator("--rate", "5", "--world", "warehouse", "--seed", "3", "--localization", "amcl")
    amcl_pose = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    cloud = ros.latest(ParticleCloud, "particle_cloud", qos_profile_sensor_data)
    truth = ros.latest(Odometry, "ground_truth", qos_profile_sensor_data)
    tf = ros.latest(TFMessage, "tf", 10)
    pub = ros.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)

    # garbage first: NaN, wrong frame, a negative covariance — all ignored, the simulator keeps serving
    bad = initial_pose(math.nan, 0.0, 0.0)
    pub.publish(bad)
    wrong_frame = initial_pose(1.0, 0.0, 0.0)
    wrong_frame.header.frame_id = "odom"
    pub.publish(wrong_frame)
    pub.publish(initial_pose(1.0, 0.0, 0.0, (-1.0, 0.2, 0.1)))

    # the docked robot at (0, 0): a right initial pose with RViz's 2D Pose Estimate covariance
    msg = ros.publish_until(
        PoseWithCovarianceStamped,
        "initialpose",
        initial_pose(0.0, 0.0, 0.0, (0.25, 0.25, 0.0685)),
        amcl_pose,
        "amcl_pose",
        predicate=lambda m: abs(m.pose.pose.position.x) < 0.3,
        timeout=20.0,
    )
    assert msg.header.frame_id == "map" and msg.pose.covariance[0] > 0.0 and msg.pose.covariance[35] > 0.0
    particles = ros.wait_for(cloud, lambda m: len(m.particles) >= 500, what="particle_cloud")
    assert particles.header.frame_id == "map"
    assert abs(sum(p.weight for p in particles.particles) - 1.0) < 1e-6
    gt = ros.wait_for(truth, what="ground_truth")
    assert gt.header.frame_id == "map" and abs(gt.pose.pose.position.x) < 0.05
    ros.wait_for(tf, lambda m: any(t.header.frame_id == "map" and t.child_frame_id == "odom" for t in m.transforms))

    # set_initial_pose service: a pose 0.3 m off with a covariance: the estimate moves there. Every amcl_pose is
    # kept: the forced update at the next scan (0.02 s of wall time at 5x) may pull the estimate back toward the
    # truth the lidar sees before a look at the latest message could catch it.
    poses: list[PoseWithCovarianceStamped] = []
    ros.node.create_subscription(PoseWithCovarianceStamped, "amcl_pose", poses.append, LATCHED)
    ros.wait_for(lambda: poses or None, what="the latched amcl_pose (the subscription matched)")
    req = SetInitialPose.Request()
    req.pose = initial_pose(0.3, 0.0, 0.0, (0.04, 0.04, 0.005))
    ros.service(SetInitialPose, "set_initial_pose", req)
    ros.wait_for(
        lambda: [m for m in poses if m.pose.pose.position.x > 0.15] or None, what="amcl_pose after set_initial_pose"
    )
    # nomotion updates pull it back toward the truth the lidar sees (x = 0). The set pose's 0.2 m deviation puts the
    # truth inside the cloud: one update brought it to 0.18 m, eight to about 0.1 (2026-11-27). With 0.1 m, as before,
    # the cloud held few particles near the truth and its mean settled near 0.2 m (0.197 and 0.203 after 7 and 8).
    xs = []
    for _ in range(8):
        ros.service(Empty, "request_nomotion_update", Empty.Request())
        time.sleep(0.3)
        xs.append(round(ros.wait_for(amcl_pose, what="amcl_pose").pose.pose.position.x, 3))
        if xs[-1] < 0.2:
            break
    assert xs[-1] < 0.2, f"amcl_pose x after each nomotion update: {xs}"

    # global localization: the cloud spreads over the map
    ros.service(Empty, "reinitialize_global_localization", Empty.Request())
    spread = ros.wait_for(
        cloud,
        lambda m: max(p.pose.position.x for p in m.particles) - min(p.pose.position.x for p in m.particles) > 10.0,
        what="a particle cloud spread over the map",
    )
    assert len(spread.particles) >= 500
    yaws = [quaternion_to_yaw(p.pose.orientation) for p in spread.particles]
    assert max(yaws) - min(yaws) > 5.0
    # the simulator still answers: drive a little
    cmd = ros.node.create_publisher(Twist, "cmd_vel", 10)
    cmd.publish(Twist())


def test_at_max_rate_every_estimate_has_the_ground_truth_of_its_stamp(start_simulator, ros, request) -> None:
    """ground_truth is bounded per wall second (as odom) and a still robot's repeats more, yet beside every
    amcl_pose comes the truth with the same stamp: `tb4 run` pairs each estimate with the truth of its moment.
    (Before, the estimate sent as the robot stopped had none: its truth was a repeat, held back.)"""
    from nav2_msgs.action import NavigateToPose

    from tb4.ros.background import BackgroundNode
    from tb4.ros.convert import pose_stamped

    from .test_route_server import localize_and_undock

    start_simulator("--rate", "max", "--hold", "--world", "warehouse")
    deep = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)  # nothing dropped on our side
    truths: list[float] = []
    estimates: list[float] = []

    def stamp(msg) -> float:
        return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    # a reader that keeps up (rclpy's C++ events executor): ground_truth keeps a wall second of messages
    # (GROUND_TRUTH_DEPTH) and amcl_pose is latched, so a reader further behind would lose some on the way
    watcher = BackgroundNode("truth_watcher", events_executor=True)
    arrivals: list[tuple[float, str, float]] = []  # (wall time, topic, stamp): for the report of a failure

    def on_truth(m: Odometry) -> None:
        truths.append(stamp(m))
        arrivals.append((time.monotonic(), "truth", truths[-1]))

    def on_estimate(m: PoseWithCovarianceStamped) -> None:
        estimates.append(stamp(m))
        arrivals.append((time.monotonic(), "estimate", estimates[-1]))

    watcher.node.create_subscription(Odometry, "ground_truth", on_truth, deep)
    watcher.node.create_subscription(PoseWithCovarianceStamped, "amcl_pose", on_estimate, deep)
    watcher.start()
    request.addfinalizer(watcher.close)
    localize_and_undock(ros)
    # both streams reach the watcher before the drive (stress run s31: its ground_truth reader matched so late
    # that only the drive's last three estimates came after the first truth): the truth flows all the time, an
    # estimate is asked for with a filter update that needs no motion
    deadline = time.monotonic() + 30.0
    while not (truths and estimates):
        assert time.monotonic() < deadline, f"the watcher got {len(truths)} truths and {len(estimates)} estimates"
        if not estimates:
            ros.service(Empty, "request_nomotion_update", Empty.Request())
        time.sleep(0.5)
    goal = NavigateToPose.Goal()
    goal.pose = pose_stamped((-4.0, 1.0, math.pi))
    goal.pose.header.frame_id = "map"
    status, _ = ros.action(NavigateToPose, "navigate_to_pose", goal, timeout=120.0)
    assert status == 4  # succeeded
    # the two streams come from two writers: the last estimates can be in before their truths (stress run s33: the
    # estimate of 71.6 s was, the truths had reached 71.45 s). The truth flows on (bounded) while the robot stands.
    # Waiting for a truth at or after the last estimate was not enough (a CI-like run: the last estimate's truth
    # was not in, and no truth after it was listed either): wait for each estimate's own truth.
    paired = [t for t in estimates if t >= truths[0]]
    assert len(paired) >= 5
    wait_until(lambda: not set(paired) - set(truths), 30.0)
    truth_stamps = set(truths)
    missing = sorted(set(paired) - truth_stamps)
    near = {m: sorted(t for t in truth_stamps if abs(t - m) < 0.3) for m in missing[:3]}
    if missing:  # what came around the first one, in order of arrival, and who writes the two topics (stress runs
        # s33, s34 and s36 saw one such estimate in the Jazzy stage, always right after the topics test on one worker)
        first = next(i for i, a in enumerate(arrivals) if a[1] == "estimate" and a[2] == missing[0])
        t0 = arrivals[first][0]
        around = [(round(w - t0, 3), topic, s) for w, topic, s in arrivals[max(0, first - 8) : first + 8]]
        writers = {
            topic: [f"{i.node_namespace}/{i.node_name}" for i in watcher.node.get_publishers_info_by_topic(topic)]
            for topic in ("amcl_pose", "ground_truth")
        }
        backwards = [(a, b) for a, b in itertools.pairwise(truths) if b < a]  # another writer's, or reordered
        raise AssertionError(
            f"no truth at {missing[:5]} in 30 s (near: {near}; {len(paired)} paired, {len(truths)} truths, "
            f"stamps going back: {backwards[:3]}); "
            f"arrivals around it (wall s, topic, stamp): {around}; writers: {writers}"
        )
