"""`tb4 press BUTTON [--hold S]`: press one of the Create 3's faceplate buttons on the simulated robot.

The simulator then publishes the press and the release on `interface_buttons`, as the robot does, so a script
that reacts to buttons (the TurtleBot 4 manual's first node) can be tested without hands.
"""

from __future__ import annotations

import argparse
import math
import sys

from tb4.cli._deliver import deliver_once
from tb4.rosenv import require_ros

__all__ = ["register", "button_name"]

_NAMES = {"1": "button_1", "button_1": "button_1", "2": "button_2", "button_2": "button_2"}
_NAMES.update({"power": "button_power", "button_power": "button_power", "p": "button_power"})


def button_name(text: str) -> str:
    """'1' -> button_1, '2' -> button_2, 'power' -> button_power (ValueError for anything else)."""
    key = text.strip().lower()
    if key not in _NAMES:
        raise ValueError(f"unknown button {text!r}: use 1, 2 or power")
    return _NAMES[key]


def _hold(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not (math.isfinite(value) and 0.0 < value <= 60.0):
        raise argparse.ArgumentTypeError(f"hold must be within (0, 60] s, got {text!r}")
    return value


def _cmd_press(args: argparse.Namespace) -> int:
    try:
        name = button_name(args.button)
    except ValueError as exc:
        print(f"tb4 press: {exc}", file=sys.stderr)
        return 2
    require_ros()
    import rclpy
    from irobot_create_msgs.msg import Button

    from tb4.ros.convert import duration_msg
    from tb4.ros.robot.services import PRESS_TOPIC

    rclpy.init()
    node = rclpy.create_node("tb4_press", namespace=args.namespace or "/")
    try:
        publisher = node.create_publisher(Button, PRESS_TOPIC, 10)
        msg = Button()
        msg.header.frame_id = name
        msg.is_pressed = True
        msg.last_pressed_duration = duration_msg(args.hold)
        if not deliver_once(node, publisher, PRESS_TOPIC, msg, args.timeout, "tb4 press", "is `tb4 sim` running?"):
            return 1
        print(f"pressed {name} for {args.hold:g} s")
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def register(sub: argparse._SubParsersAction) -> None:
    press = sub.add_parser("press", help="press a Create 3 button (1, 2 or power) on the simulated robot")
    press.add_argument("button", help="1, 2 or power")
    press.add_argument("--hold", type=_hold, default=0.2, help="seconds the button is held (default 0.2)")
    press.add_argument("--namespace", default="")
    press.add_argument("--timeout", type=float, default=10.0, help="seconds to wait for the simulator")
    press.set_defaults(func=_cmd_press)
