"""`tb4 view`: serve the live web viewer (map, costmaps, robot, scan, plan, tasks; RViz's pose and goal tools)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from tb4.cli._arguments import number
from tb4.rosenv import require_ros

__all__ = ["register", "add_view_arguments", "DEFAULT_PORT"]

DEFAULT_PORT = 8765


def _namespace(text: str) -> str:
    from tb4.viewer.protocol import ProtocolError, normalize_namespace

    try:
        return normalize_namespace(text)
    except ProtocolError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_view_arguments(parser: argparse.ArgumentParser) -> None:
    """--port, --host and --allow-host."""
    port = number("port", 0, 65535, integer=True)
    parser.add_argument("--port", type=port, default=DEFAULT_PORT, help=f"viewer port (default {DEFAULT_PORT})")
    parser.add_argument(
        "--host",
        default="127.0.0.1",
        help="address to listen on (default 127.0.0.1: this machine only; 0.0.0.0 lets the network drive the robot, "
        "with the token in the printed URL)",
    )
    parser.add_argument(
        "--allow-host",
        action="append",
        default=[],
        metavar="NAME",
        help="another Host name to answer to (a DNS alias or a proxy's name); others are refused (repeatable)",
    )


def _cmd_view(args: argparse.Namespace) -> int:
    require_ros()
    from tb4.config import ConfigError
    from tb4.extras import MissingExtraError, require_extra

    try:
        require_extra("viewer")
    except MissingExtraError as exc:
        print(f"tb4 view: {exc}", file=sys.stderr)
        return 2
    from tb4.viewer.launch import is_loopback, start_viewer_in_thread

    if not is_loopback(args.host):
        print(
            f"tb4 view: warning: listening on {args.host}: anyone who can reach it and has the URL's token can move "
            "the robot",
            flush=True,
        )
    try:
        handle = start_viewer_in_thread(
            namespace=args.namespace, port=args.port, host=args.host, world=args.world, allow_hosts=args.allow_host
        )
    except (OSError, ValueError, ConfigError, RuntimeError) as exc:
        print(f"tb4 view: {exc}", file=sys.stderr)
        return 2
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    print(f"tb4 view serving {handle.url} (namespace {args.namespace or '/'}); Ctrl-C to stop", flush=True)
    try:
        while not stop.wait(0.5):
            if not handle.running:
                print("tb4 view: the web server stopped", file=sys.stderr)
                return 1
            if handle.bridge is not None and not getattr(handle.bridge, "alive", True):
                print("tb4 view: the ROS side stopped", file=sys.stderr)
                return 1
    finally:
        handle.stop()
        print("tb4 view stopped", flush=True)
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    view = sub.add_parser("view", help="live web viewer with RViz's 2D Pose Estimate and Nav2 Goal tools")
    add_view_arguments(view)
    view.add_argument(
        "--namespace", type=_namespace, default="", help="robot namespace to show first, e.g. robot1 (pick others live)"
    )
    view.add_argument(
        "--world",
        default=None,
        help="world whose dock and named places to show (default: the one the simulator announces)",
    )
    view.set_defaults(func=_cmd_view)
