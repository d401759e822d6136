"""`tb4 kidnap X Y [HEADING]`: lift the simulated robot and put it down elsewhere (map frame), as a person would.

The robot reports kidnap_status while in the air (about a second of sim time), its wheels drop, any drive goal
aborts, and its odometry turns with the heading change but keeps its position (nothing rolled): scripts that
must notice a kidnap can be tested.
"""

from __future__ import annotations

import argparse
import math
import sys

from tb4.cli._deliver import deliver_once
from tb4.cli.cmd_pose import _finite
from tb4.core.directions import parse_heading
from tb4.rosenv import require_ros

__all__ = ["register"]


def _cmd_kidnap(args: argparse.Namespace) -> int:
    try:
        heading = parse_heading(args.heading)
    except ValueError as exc:
        print(f"tb4 kidnap: {exc}", file=sys.stderr)
        return 2
    require_ros()
    import rclpy
    from geometry_msgs.msg import PoseStamped

    from tb4.ros.convert import yaw_to_quaternion
    from tb4.ros.robot.services import KIDNAP_TOPIC

    rclpy.init()
    node = rclpy.create_node("tb4_kidnap", namespace=args.namespace or "/")
    try:
        publisher = node.create_publisher(PoseStamped, KIDNAP_TOPIC, 10)
        msg = PoseStamped()
        msg.header.frame_id = "map"
        msg.pose.position.x, msg.pose.position.y = args.x, args.y
        yaw = math.radians(heading)
        msg.pose.orientation = yaw_to_quaternion(yaw)
        if not deliver_once(node, publisher, KIDNAP_TOPIC, msg, args.timeout, "tb4 kidnap", "is `tb4 sim` running?"):
            return 1
        print(f"kidnapped the robot to ({args.x:g}, {args.y:g}) heading {heading:g} deg")
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def register(sub: argparse._SubParsersAction) -> None:
    kidnap = sub.add_parser("kidnap", help="lift the simulated robot and put it down at X Y [HEADING] (map frame)")
    kidnap.add_argument("x", type=_finite)
    kidnap.add_argument("y", type=_finite)
    kidnap.add_argument("heading", nargs="?", default="0", help="degrees or a direction name (default: north)")
    kidnap.add_argument("--namespace", default="")
    kidnap.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the simulator")
    kidnap.set_defaults(func=_cmd_kidnap)
