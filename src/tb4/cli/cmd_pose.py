"""`tb4 pose X Y [HEADING]`: publish one pose on `initialpose`, as RViz's "2D Pose Estimate" tool does."""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from tb4.cli._arguments import add_pose_arguments, add_robot_arguments
from tb4.cli._deliver import cli_node, wait_for_readers
from tb4.core.directions import parse_heading

__all__ = ["register", "PoseDelivery"]

# amcl_pose this close to the sent pose confirms the localizer took it. A particle filter reports the mean of
# particles drawn from the pose's covariance (0.5 m, 15 deg here), so it lands near the pose, not on it.
SETTLE = 0.4  # s without newly discovered readers before publishing
REPUBLISH = 1.0  # s between publications while the localizer has not reported the pose
ACK_TIMEOUT = 3.0  # s for other readers to acknowledge (one DDS heartbeat period) once the simulator has the pose


def _cmd_pose(args: argparse.Namespace) -> int:
    try:
        heading = parse_heading(args.heading)
    except ValueError as exc:
        print(f"tb4 pose: {exc}", file=sys.stderr)
        return 2
    with cli_node("tb4_pose", args.namespace) as node:
        from geometry_msgs.msg import PoseWithCovarianceStamped

        from tb4.ros.convert import pose_stamped

        yaw = math.radians(heading)
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = node.get_clock().now().to_msg()
        msg.pose.pose = pose_stamped((args.x, args.y, yaw)).pose
        msg.pose.covariance[0] = msg.pose.covariance[7] = 0.25
        msg.pose.covariance[35] = 0.0685
        delivery = PoseDelivery(node, args.x, args.y, yaw, args.timeout)
        problem = delivery.send(msg, args.wait_for)
    if problem is not None:
        print(f"tb4 pose: {problem}", file=sys.stderr)
        return 1
    print(f"published initialpose ({args.x:g}, {args.y:g}) heading {heading:g} deg")
    return 0


class PoseDelivery:
    """Publish one initial pose and return as soon as it has arrived where it matters.

    Arrived means: the localizer (the simulator's amcl) reports the new pose on `amcl_pose` (and, when others
    subscribe too, they acknowledged it within ACK_TIMEOUT, else a warning), or, with
    `--wait-for NODE`, that node's subscription is matched and every matched reader acknowledged the sample
    (reliable delivery). The writer is new, so DDS acknowledges within one heartbeat of the match; nothing here
    sleeps for a fixed time. Every wait is bounded by `timeout`.
    """

    def __init__(self, node: Any, x: float, y: float, yaw: float, timeout: float) -> None:
        from geometry_msgs.msg import PoseWithCovarianceStamped

        from tb4.ros.qos import LATCHED

        self.node = node
        self.target = (x, y, yaw)
        self.deadline = time.monotonic() + timeout
        self.timeout = timeout
        self.publisher = node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        self.confirmed = False
        node.create_subscription(PoseWithCovarianceStamped, "amcl_pose", self._on_amcl, LATCHED)

    def _on_amcl(self, msg: Any) -> None:
        from tb4.core.geometry import same_pose
        from tb4.ros.convert import quaternion_to_yaw

        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        if same_pose((p.x, p.y, quaternion_to_yaw(q)), self.target):
            self.confirmed = True

    def _spin(self, seconds: float) -> None:
        import rclpy

        rclpy.spin_once(self.node, timeout_sec=seconds)

    def _named_subscriber_matched(self, name: str) -> bool:
        infos = self.node.get_subscriptions_info_by_topic("initialpose")
        named = any(i.node_name == name.split("/")[-1] for i in infos)
        return named and self.publisher.get_subscription_count() >= len(infos)

    def send(self, msg: Any, wait_for: str | None) -> str | None:
        """Deliver `msg`; None when delivered, else what went wrong."""
        from rclpy.duration import Duration

        # Discovery finds readers one by one: publish once every discovered reader is matched and none has
        # turned up for SETTLE seconds (a reader that has not discovered this writer would drop the sample).
        def ready(matched: int) -> bool:
            return matched > 0 and (not wait_for or self._named_subscriber_matched(wait_for))

        if not wait_for_readers(self.node, self.publisher, "initialpose", self.deadline, SETTLE, self._spin, ready):
            who = f"node '{wait_for}'" if wait_for else "nobody"
            return (
                f"{who} subscribes to 'initialpose' after {self.timeout:g} s "
                "(is the simulator or the create_path tutorial running?)"
            )
        self.confirmed = False
        self.publisher.publish(msg)
        published = time.monotonic()
        # Discovery is per side: this writer can have matched the localizer's reader before that reader has
        # matched this writer, and a volatile sample sent in between never reaches it (one `tb4 pose` in seven
        # against a fresh simulator at --rate max). So the pose goes out again every REPUBLISH seconds until the
        # localizer reports it, as upstream's setInitialPose does.
        localizer = False
        while time.monotonic() < self.deadline and not (localizer and self.confirmed):
            self._spin(0.01)
            localizer = not wait_for and self.node.count_publishers("amcl_pose") > 0  # discovery may lag
            if not localizer and self.publisher.wait_for_all_acked(Duration(nanoseconds=10_000_000)):
                return None
            if localizer and not self.confirmed and time.monotonic() - published >= REPUBLISH:
                self.publisher.publish(msg)
                published = time.monotonic()
        if localizer and not self.confirmed:
            return f"the localizer did not report the new pose on 'amcl_pose' within {self.timeout:g} s"
        if localizer and self.publisher.get_subscription_count() <= 1:
            return None  # only the simulator listens, and it has the pose
        # Others listen too (a tutorial collecting poses, a recorder): give them time to acknowledge. A reader in a
        # process that was killed stays matched until its DDS lease runs out and never answers, so this warns.
        grace = max(0.0, min(ACK_TIMEOUT, self.deadline - time.monotonic()))
        if not self.publisher.wait_for_all_acked(Duration(nanoseconds=int(grace * 1e9))):
            print(
                f"tb4 pose: not every subscriber acknowledged within {grace:.1f} s (one may have gone away)",
                file=sys.stderr,
            )
        return None


def register(sub: argparse._SubParsersAction) -> None:
    pose = sub.add_parser("pose", help="publish one pose on initialpose (like RViz's 2D Pose Estimate)")
    add_pose_arguments(pose)
    add_robot_arguments(pose, waits_for="delivery")
    pose.add_argument(
        "--wait-for",
        metavar="NODE",
        help="deliver to this subscriber node (e.g. a tutorial) instead of waiting for the localizer's amcl_pose",
    )
    pose.set_defaults(func=_cmd_pose)
