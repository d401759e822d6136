"""Durations and stamps as ROS carries them, (sec, nanosec), to and from float seconds, in one place."""

from __future__ import annotations

import math
from typing import Protocol

__all__ = ["NANOSECONDS_PER_SECOND", "SecNanosec", "to_sec_nanosec", "from_sec_nanosec", "seconds_of"]

NANOSECONDS_PER_SECOND = 1_000_000_000


class SecNanosec(Protocol):
    """Anything shaped like builtin_interfaces/Time or Duration."""

    sec: int
    nanosec: int


def to_sec_nanosec(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a non-negative duration; NaN, infinities and negatives become 0 (a Duration is unsigned
    in every action that takes one), and nanosec never rounds up to a full second."""
    seconds = max(0.0, float(seconds)) if math.isfinite(seconds) else 0.0
    whole = math.floor(seconds)
    return int(whole), min(int(round((seconds - whole) * 1e9)), NANOSECONDS_PER_SECOND - 1)


def from_sec_nanosec(sec: int, nanosec: int) -> float:
    """Float seconds of a (sec, nanosec) pair (builtin_interfaces Time or Duration)."""
    return float(sec) + float(nanosec) * 1e-9


def seconds_of(stamp: SecNanosec) -> float:
    """Float seconds of a Time or Duration message (duck-typed, so callers need not import ROS)."""
    return from_sec_nanosec(stamp.sec, stamp.nanosec)
