"""Argument types and argument groups the `tb4` sub-commands share, so each check and its message exist once."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

__all__ = ["number", "add_pose_arguments", "add_robot_arguments"]


def number(
    what: str, low: float = -math.inf, high: float = math.inf, *, integer: bool = False, above_low: bool = False
) -> Callable[[str], float]:
    """An argparse type: a finite number (an integer with `integer`) within [low, high] ((low, high] with
    `above_low`), or an error naming `what` and the range."""
    if math.isinf(low) and math.isinf(high):
        expected = "a finite number"
    elif above_low:
        expected = f"a number within ({low:g}, {high:g}]"
    else:
        expected = f"a number between {low:g} and {high:g}"

    def parse(text: str) -> float:
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be {expected}, got {text!r}") from None
        too_low = value <= low if above_low else value < low
        if not math.isfinite(value) or too_low or value > high:
            raise argparse.ArgumentTypeError(f"{what} must be {expected}, got {text!r}")
        return value

    return parse


def add_pose_arguments(parser: argparse.ArgumentParser) -> None:
    """X Y [HEADING] in the map frame (tb4 pose, tb4 kidnap)."""
    parser.add_argument("x", type=number("x"))
    parser.add_argument("y", type=number("y"))
    parser.add_argument("heading", nargs="?", default="0", help="degrees or a direction name (default: north)")


def add_robot_arguments(parser: argparse.ArgumentParser, waits_for: str = "the simulator") -> None:
    """--namespace and --timeout of a command that talks to one robot."""
    parser.add_argument("--namespace", default="")
    parser.add_argument("--timeout", type=float, default=10.0, help=f"seconds to wait for {waits_for}")
