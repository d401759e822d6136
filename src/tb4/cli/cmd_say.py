"""`tb4 say TEXT`: publish one command on `user_input` for gpt_node (like `ros2 topic pub --once`)."""

from __future__ import annotations

import argparse
import sys
import time

from tb4.core.waits import wait_until
from tb4.rosenv import require_ros

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
    require_ros()
    import rclpy
    from rclpy.duration import Duration
    from std_msgs.msg import String

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node(args.node_name, namespace=args.namespace or "/", context=context)
    try:
        publisher = node.create_publisher(String, "user_input", 10)
        if not wait_until(lambda: publisher.get_subscription_count() > 0, args.timeout, period=0.05):
            print(
                f"tb4 say: nobody subscribes to '{publisher.topic_name}' after {args.timeout:g} s "
                "(is the natural_language_nav tutorial running? `tb4 run natural_language_nav`)",
                file=sys.stderr,
            )
            return 1
        time.sleep(0.2)  # discovery is two-way: give the subscriber a moment to match us too
        publisher.publish(String(data=text))
        acked = publisher.wait_for_all_acked(Duration(seconds=min(args.timeout, 5.0)))
        if not acked:
            print("tb4 say: the command was sent but not acknowledged", file=sys.stderr)
            return 1
        print(f"published on {publisher.topic_name}: {text!r}")
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)


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
