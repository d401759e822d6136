"""Natural-language navigation: type commands (`tb4 say "Go to the wooden object"`), the robot drives, safely.

gpt_node turns each command into a short program (offline interpreter unless OPENAI_API_KEY or --base-url is set;
then any OpenAI-compatible server: OpenAI, Ollama, vLLM, llama.cpp), checks it with the safe executor and runs it
unless the parking brake is on.
ROS parameters can also be given the ROS way: `--ros-args -p parking_brake:=false -p model_name:=llama3`.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence

from tb4.language.model_client import MODEL_ENV, default_model
from tb4.rosenv import apply_safe_ros_defaults, require_ros

__all__ = ["WORLD", "SUMMARY", "main", "build_parser"]

WORLD = "depot"
SUMMARY = "drive by typed commands through a language model (or the offline interpreter), safely"


def _on_off(text: str) -> bool:
    value = text.strip().lower()
    if value in ("on", "true", "1", "yes"):
        return True
    if value in ("off", "false", "0", "no"):
        return False
    raise argparse.ArgumentTypeError(f"expected on or off, got {text!r}")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="natural_language_nav", description=__doc__)
    parser.add_argument("--namespace", default="", help="robot namespace, e.g. robot1")
    parser.add_argument(
        "--world",
        default=os.environ.get("TB4_WORLD") or WORLD,
        help="world whose destinations the commands may name (default: $TB4_WORLD, else depot)",
    )
    parser.add_argument(
        "--destinations-file",
        default="",
        help="the site's named places (and map) in a file of their own, for a real robot; overrides --world",
    )
    parser.add_argument(
        "--backend",
        choices=("offline", "openai"),
        default=None,
        help="default: openai if OPENAI_API_KEY or --base-url is set, else offline",
    )
    parser.add_argument("--model-name", default=default_model(), help=f"default: {default_model()} (${MODEL_ENV})")
    parser.add_argument("--base-url", default="", help="OpenAI-compatible server, e.g. http://127.0.0.1:11434/v1")
    parser.add_argument("--timeout", type=float, default=30.0, help="seconds per model request")
    parser.add_argument("--max-retries", type=int, default=2)
    parser.add_argument(
        "--parking-brake", type=_on_off, default=True, help="on (default, like upstream): log programs, do not run"
    )
    parser.add_argument("--allowed-publisher", default="", help="accept commands only from this node, e.g. /tb4_say")
    parser.add_argument("--require-confirmation", action="store_true", help="run a program only after a 'yes'")
    parser.add_argument("--max-commands", type=int, default=0, help="exit after N commands (0: until Ctrl-C)")
    parser.add_argument("--command-timeout", type=float, default=1800.0, help="with --max-commands: give up after S s")
    parser.add_argument("--skip-preamble", action="store_true", help="do not dock/undock first")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    raw = list(sys.argv[1:] if argv is None else argv)
    ros_args = raw[raw.index("--ros-args") :] if "--ros-args" in raw else []
    ours = raw[: len(raw) - len(ros_args)]
    args, _unknown = build_parser().parse_known_args(ours)
    apply_safe_ros_defaults()
    require_ros()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from tb4.language.gpt_node import GptNode, GptNodeOptions
    from tb4.tutorials.common import close_navigator, open_navigator, start_on_dock

    if not rclpy.ok():
        rclpy.init(args=["natural_language_nav", *ros_args])
    navigator = open_navigator(args.namespace)
    node = None
    executor = None
    try:
        if not args.skip_preamble:
            start_on_dock(navigator)
        options = GptNodeOptions(
            openai_api_key="",  # from the openai_api_key parameter (--ros-args) or OPENAI_API_KEY
            model_name=args.model_name,
            parking_brake=args.parking_brake,
            base_url=args.base_url,
            backend=args.backend or "",
            world=args.world,
            destinations_file=args.destinations_file,
            allowed_publisher=args.allowed_publisher,
            require_confirmation=args.require_confirmation,
            timeout=args.timeout,
            max_retries=args.max_retries,
        )
        try:
            node = GptNode(navigator, options, namespace=args.namespace)
        except ValueError as exc:
            navigator.error(f"natural_language_nav: {exc}")
            return 2
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        if node.parking_brake:
            node.warn("The parking brake is on: programs are shown, not run. Start with --parking-brake off to drive.")
        print('natural_language_nav ready: send commands with tb4 say "Go to the wooden object"', flush=True)
        deadline = time.monotonic() + args.command_timeout
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
            if args.max_commands and len(node.outcomes) >= args.max_commands:
                break
            if args.max_commands and time.monotonic() > deadline:
                node.error(f"gave up waiting for {args.max_commands} commands after {args.command_timeout:g} s")
                return 1
        failed = [o for o in node.outcomes if o.status == "failed"]
        return 1 if failed else 0
    except KeyboardInterrupt:
        return 0
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.shutdown()
        close_navigator(navigator)


if __name__ == "__main__":
    sys.exit(main())
