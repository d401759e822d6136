"""`tb4 press BUTTON [--hold S]`: press one of the Create 3's faceplate buttons on the simulated robot.

The simulator then publishes the press and the release on `interface_buttons`, as the robot does, so a script
that reacts to buttons (the TurtleBot 4 manual's first node) can be tested without hands.
"""

from __future__ import annotations

import argparse
import sys

from tb4.cli._arguments import add_robot_arguments, number
from tb4.cli._deliver import cli_node, deliver_once

__all__ = ["register", "button_name"]

_NAMES = {"1": "button_1", "button_1": "button_1", "2": "button_2", "button_2": "button_2"}
_NAMES.update({"power": "button_power", "button_power": "button_power", "p": "button_power"})


def button_name(text: str) -> str:
    """'1' -> button_1, '2' -> button_2, 'power' -> button_power (ValueError for anything else)."""
    key = text.strip().lower()
    if key not in _NAMES:
        raise ValueError(f"unknown button {text!r}: use 1, 2 or power")
    return _NAMES[key]


def _cmd_press(args: argparse.Namespace) -> int:
    try:
        name = button_name(args.button)
    except ValueError as exc:
        print(f"tb4 press: {exc}", file=sys.stderr)
        return 2
    with cli_node("tb4_press", args.namespace) as node:
        from irobot_create_msgs.msg import Button

        from tb4.ros.convert import duration_msg
        from tb4.ros.robot.services import PRESS_TOPIC

        publisher = node.create_publisher(Button, PRESS_TOPIC, 10)
        msg = Button(is_pressed=True, last_pressed_duration=duration_msg(args.hold))
        msg.header.frame_id = name
        if not deliver_once(node, publisher, PRESS_TOPIC, msg, args.timeout, "tb4 press", "is `tb4 sim` running?"):
            return 1
    print(f"pressed {name} for {args.hold:g} s")
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    press = sub.add_parser("press", help="press a Create 3 button (1, 2 or power) on the simulated robot")
    press.add_argument("button", help="1, 2 or power")
    hold = number("hold (seconds)", 0.0, 60.0, above_low=True)
    press.add_argument("--hold", type=hold, default=0.2, help="seconds the button is held (default 0.2)")
    add_robot_arguments(press)
    press.set_defaults(func=_cmd_press)
