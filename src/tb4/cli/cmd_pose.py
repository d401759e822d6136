"""`tb4 pose X Y [HEADING]`: publish one pose on `initialpose`, as RViz's "2D Pose Estimate" tool does."""

from __future__ import annotations

import argparse
import math
import sys

from tb4.cli._deliver import deliver_once
from tb4.rosenv import require_ros

__all__ = ["register", "parse_heading"]

DIRECTIONS = {
    "NORTH": 0,
    "NORTH_WEST": 45,
    "WEST": 90,
    "SOUTH_WEST": 135,
    "SOUTH": 180,
    "SOUTH_EAST": 225,
    "EAST": 270,
    "NORTH_EAST": 315,
}


def parse_heading(text: str) -> float:
    """Degrees (map-relative, 0 = north = +x, 90 = west) from a number or a direction name."""
    key = text.strip().upper().replace("-", "_").replace(" ", "_")
    if key in DIRECTIONS:
        return float(DIRECTIONS[key])
    try:
        value = float(text)
    except ValueError:
        names = ", ".join(d.lower() for d in DIRECTIONS)
        raise ValueError(f"heading must be degrees or a direction ({names}), got {text!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"heading must be finite, got {text!r}")
    return value


def _finite(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _cmd_pose(args: argparse.Namespace) -> int:
    try:
        heading = parse_heading(args.heading)
    except ValueError as exc:
        print(f"tb4 pose: {exc}", file=sys.stderr)
        return 2
    require_ros()
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped

    rclpy.init()
    node = rclpy.create_node("tb4_pose", namespace=args.namespace or "/")
    try:
        publisher = node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = node.get_clock().now().to_msg()
        msg.pose.pose.position.x = args.x
        msg.pose.pose.position.y = args.y
        yaw = math.radians(heading)
        msg.pose.pose.orientation.z = math.sin(yaw / 2)
        msg.pose.pose.orientation.w = math.cos(yaw / 2)
        msg.pose.covariance[0] = msg.pose.covariance[7] = 0.25
        msg.pose.covariance[35] = 0.0685
        if not deliver_once(
            node,
            publisher,
            "initialpose",
            msg,
            args.timeout,
            "tb4 pose",
            "is the simulator or the create_path tutorial running?",
        ):
            return 1
        print(f"published initialpose ({args.x:g}, {args.y:g}) heading {heading:g} deg")
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def register(sub: argparse._SubParsersAction) -> None:
    pose = sub.add_parser("pose", help="publish one pose on initialpose (like RViz's 2D Pose Estimate)")
    pose.add_argument("x", type=_finite)
    pose.add_argument("y", type=_finite)
    pose.add_argument("heading", nargs="?", default="0", help="degrees or a direction name (default: north)")
    pose.add_argument("--namespace", default="")
    pose.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for a subscriber")
    pose.set_defaults(func=_cmd_pose)
