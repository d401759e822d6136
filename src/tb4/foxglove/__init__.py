"""Serving a simulation, or a robot, live to the Foxglove app: `tb4 sim --foxglove [PORT]`, `tb4 run ... --foxglove`.

live.py holds FoxgloveLive: the Foxglove SDK's WebSocket server (the [foxglove] extra) and a node in a context of
its own that forwards the topics to it as received, raw CDR with their ros2msg schemas. reframe.py cuts PoseArray
views out of the particle cloud and the goals, which the app's 3D panel does not draw as they are. The app's
layout and an RViz config for the same topics are in tb4.displays.

This module is what the command line needs (the options and their checks); it imports neither the SDK nor rclpy.

Who may connect: the SDK's server checks neither the Host nor the Origin of a connection, and has no token, so it
listens on loopback only unless the user names another address and says, with a second option, that anyone who
reaches it may read the robot's topics. It serves no capability a client could command the robot with.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

__all__ = [
    "DEFAULT_HOST",
    "DEFAULT_PORT",
    "FoxgloveError",
    "FoxgloveOptions",
    "add_foxglove_arguments",
    "foxglove_options",
]

DEFAULT_PORT = 8765  # the Foxglove app's own default for a Foxglove WebSocket connection
DEFAULT_HOST = "127.0.0.1"


class FoxgloveError(RuntimeError):
    """The Foxglove server could not start (the port is in use, the address does not resolve)."""


@dataclass(frozen=True)
class FoxgloveOptions:
    """Where to serve Foxglove: a port (0: any free one) on a listening address."""

    port: int = DEFAULT_PORT
    host: str = DEFAULT_HOST


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"the Foxglove port must be a number between 0 and 65535, got {text!r}")
    return value


def add_foxglove_arguments(parser: argparse.ArgumentParser) -> None:
    """--foxglove [PORT], --foxglove-host and --foxglove-allow-remote (`tb4 sim`, `tb4 run`).

    Args:
        parser: the sub-command's parser.
    """
    parser.add_argument(
        "--foxglove",
        nargs="?",
        const=DEFAULT_PORT,
        default=None,
        type=_port,
        metavar="PORT",
        help=f"serve the robots' topics to the Foxglove app on ws://{DEFAULT_HOST}:PORT (default {DEFAULT_PORT}; "
        "0: any free port); needs the [foxglove] extra",
    )
    parser.add_argument(
        "--foxglove-host",
        default=DEFAULT_HOST,
        metavar="HOST",
        help=f"address Foxglove listens on (default {DEFAULT_HOST}: this machine only); another address needs "
        "--foxglove-allow-remote",
    )
    parser.add_argument(
        "--foxglove-allow-remote",
        action="store_true",
        help="accept a --foxglove-host beyond loopback: anyone who reaches it can read the robots' topics (the "
        "Foxglove server checks no Host, Origin or token)",
    )


def foxglove_options(args: argparse.Namespace) -> FoxgloveOptions | None:
    """The Foxglove options a command line asked for, checked.

    Args:
        args: the parsed arguments of a parser given add_foxglove_arguments.

    Returns:
        FoxgloveOptions, or None without --foxglove.

    Raises:
        ValueError: --foxglove-host is not a loopback address and --foxglove-allow-remote was not given, or a
            Foxglove option was given without --foxglove.
    """
    from tb4.viewer.access import is_loopback, is_wildcard  # noqa: PLC0415 - plain Python, only when asked

    host = str(args.foxglove_host).strip()
    if args.foxglove is None:
        if host != DEFAULT_HOST or args.foxglove_allow_remote:
            raise ValueError("--foxglove-host and --foxglove-allow-remote need --foxglove [PORT]")
        return None
    if not host:
        raise ValueError("--foxglove-host must name an address, e.g. 127.0.0.1")
    if not is_loopback(host) and not args.foxglove_allow_remote:
        where = "every interface" if is_wildcard(host) else host
        raise ValueError(
            f"--foxglove-host {host} would serve beyond this machine ({where}): the Foxglove server checks no Host, "
            "Origin or token, so anyone who reaches it reads the robots' topics. Add --foxglove-allow-remote to "
            f"serve there anyway, or drop --foxglove-host to stay on {DEFAULT_HOST}"
        )
    return FoxgloveOptions(port=int(args.foxglove), host=host)
