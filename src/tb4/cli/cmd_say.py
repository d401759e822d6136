"""`tb4 say TEXT`: publish one command on `user_input` for gpt_node (like `ros2 topic pub --once`)."""

from __future__ import annotations

import argparse
import sys

from tb4.cli._deliver import cli_node, deliver_once

__all__ = ["register"]


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of seconds, got {text!r}") from None
    if not 0.0 < value <= 3600.0:
        raise argparse.ArgumentTypeError(f"expected seconds between 0 and 3600, got {text}")
    return value


def _cmd_say(args: argparse.Namespace) -> int:
    text = " ".join(args.text).strip()
    if not text:
        print("tb4 say: nothing to say", file=sys.stderr)
        return 2
    with cli_node(args.node_name, args.namespace) as node:  # checks that ROS is there before importing from it
        from std_msgs.msg import String

        publisher = node.create_publisher(String, "user_input", 10)
        hint = "is the natural_language_nav tutorial running? `tb4 run natural_language_nav`"
        if not deliver_once(node, publisher, publisher.topic_name, String(data=text), args.timeout, "tb4 say", hint):
            return 1
        print(f"published on {publisher.topic_name}: {text!r}")
        return 0


def register(sub: argparse._SubParsersAction) -> None:
    say = sub.add_parser(
        "say",
        help="send one command to the natural_language_nav tutorial (publishes on user_input)",
        description="Publish TEXT once on user_input (std_msgs/String), after waiting (bounded) for a subscriber.",
    )
    say.add_argument("text", nargs="+", help='the command, e.g. "Go to the wooden object"')
    say.add_argument("--namespace", default="", help="robot namespace, e.g. robot1")
    say.add_argument("--timeout", type=_positive, default=10.0, help="seconds to wait for a subscriber (default 10)")
    say.add_argument("--node-name", default="tb4_say", help="name of the publishing node (see allowed_publisher)")
    say.set_defaults(func=_cmd_say)
