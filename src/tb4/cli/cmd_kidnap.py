"""`tb4 kidnap X Y [HEADING]`: lift the simulated robot and put it down elsewhere (map frame), as a person would.

The robot reports kidnap_status while in the air (about a second of sim time), its wheels drop, any drive goal
aborts, and its odometry turns with the heading change but keeps its position (nothing rolled): scripts that
must notice a kidnap can be tested.
"""

from __future__ import annotations

import argparse
import math
import sys

from tb4.cli._arguments import add_pose_arguments, add_robot_arguments
from tb4.cli._deliver import cli_node, deliver_once
from tb4.core.directions import parse_heading

__all__ = ["register"]


def _cmd_kidnap(args: argparse.Namespace) -> int:
    try:
        heading = parse_heading(args.heading)
    except ValueError as exc:
        print(f"tb4 kidnap: {exc}", file=sys.stderr)
        return 2
    with cli_node("tb4_kidnap", args.namespace) as node:
        from tb4.ros.convert import pose_stamped
        from tb4.ros.robot.services import KIDNAP_TOPIC

        msg = pose_stamped((args.x, args.y, math.radians(heading)))
        publisher = node.create_publisher(type(msg), KIDNAP_TOPIC, 10)
        if not deliver_once(node, publisher, KIDNAP_TOPIC, msg, args.timeout, "tb4 kidnap", "is `tb4 sim` running?"):
            return 1
    print(f"kidnapped the robot to ({args.x:g}, {args.y:g}) heading {heading:g} deg")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    kidnap = sub.add_parser("kidnap", help="lift the simulated robot and put it down at X Y [HEADING] (map frame)")
    add_pose_arguments(kidnap)
    add_robot_arguments(kidnap)
    kidnap.set_defaults(func=_cmd_kidnap)
