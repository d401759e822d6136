"""What the page may send, checked before anything reaches ROS: one message type per tool, finite numbers only.

Every problem becomes a ProtocolError whose text the page shows as is; the connection stays open. A token bucket
per page turns floods into one rejection message per second instead of a flood of ROS traffic.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = [
    "ProtocolError",
    "PoseCommand",
    "CancelCommand",
    "NamespaceCommand",
    "LayersCommand",
    "PressCommand",
    "Command",
    "parse_message",
    "normalize_namespace",
    "RateLimiter",
    "MAX_MESSAGE_BYTES",
    "MAX_COORDINATE",
    "TOGGLE_LAYERS",
]

MAX_MESSAGE_BYTES = 4096
MAX_COORDINATE = 10_000.0  # m: anything farther is a bug or an attack, not a pose on a map
TOGGLE_LAYERS = ("global_costmap", "local_costmap")


class ProtocolError(ValueError):
    """A message from the page was rejected; the text says why, for the page to show."""


@dataclass(frozen=True)
class PoseCommand:
    """`initial_pose` (2D Pose Estimate) or `goal` (Nav2 Goal): a pose in the map frame."""

    kind: str
    x: float
    y: float
    yaw: float


@dataclass(frozen=True)
class CancelCommand:
    kind: str = "cancel"


@dataclass(frozen=True)
class NamespaceCommand:
    namespace: str
    kind: str = "namespace"


@dataclass(frozen=True)
class LayersCommand:
    """Which optional grid layers the page draws (the server only sends those)."""

    layers: tuple[str, ...]
    kind: str = "layers"


@dataclass(frozen=True)
class PressCommand:
    """Press one of the Create 3's faceplate buttons (the simulated robot only)."""

    button: str
    kind: str = "press"


PRESS_BUTTONS = ("button_1", "button_power", "button_2")
Command = PoseCommand | CancelCommand | NamespaceCommand | LayersCommand | PressCommand


def _number(msg: dict[str, Any], key: str, limit: float) -> float:
    if key not in msg:
        raise ProtocolError(f"'{msg['type']}' needs a number '{key}'")
    value = msg[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ProtocolError(f"'{key}' must be a number, got {type(value).__name__}")
    value = float(value)
    if not math.isfinite(value):
        raise ProtocolError(f"'{key}' must be finite, got {value}")
    if abs(value) > limit:
        raise ProtocolError(f"'{key}' = {value:g} is out of range (|{key}| <= {limit:g})")
    return value


def normalize_namespace(text: Any) -> str:
    """'' or '/robot1' style names: letters, digits and underscores per part, at most 100 characters."""
    if not isinstance(text, str):
        raise ProtocolError(f"namespace must be a string, got {type(text).__name__}")
    ns = text.strip().strip("/")
    if len(ns) > 100:
        raise ProtocolError("namespace is too long")
    if ns and not all(part.isidentifier() and part.isascii() for part in ns.split("/")):
        raise ProtocolError(f"invalid namespace {text!r}: use letters, digits and underscores, e.g. robot1")
    return f"/{ns}" if ns else ""


def _check_keys(msg: dict[str, Any], allowed: tuple[str, ...]) -> None:
    extra = sorted(set(msg) - {"type", *allowed})
    if extra:
        raise ProtocolError(f"unexpected field(s) in '{msg['type']}': {', '.join(extra)}")


def parse_message(text: str | bytes) -> Command:
    """Validate one WebSocket message from the page; raise ProtocolError saying what is wrong."""
    if isinstance(text, bytes):
        raise ProtocolError("binary messages are not accepted; send JSON text")
    if len(text) > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message too long ({len(text)} bytes, at most {MAX_MESSAGE_BYTES})")
    try:
        msg = json.loads(text, parse_constant=lambda c: math.nan)  # NaN/Infinity literals -> rejected below
    except (json.JSONDecodeError, RecursionError) as exc:
        raise ProtocolError(f"malformed message (not JSON): {exc}") from None
    if not isinstance(msg, dict):
        raise ProtocolError("a message must be a JSON object with a 'type'")
    kind = msg.get("type")
    if not isinstance(kind, str):
        raise ProtocolError("a message needs a string 'type'")
    if kind in ("initial_pose", "goal"):
        _check_keys(msg, ("x", "y", "yaw"))
        x = _number(msg, "x", MAX_COORDINATE)
        y = _number(msg, "y", MAX_COORDINATE)
        yaw = math.remainder(_number(msg, "yaw", 1000.0), 2 * math.pi)
        return PoseCommand(kind, x, y, yaw)
    if kind == "cancel":
        _check_keys(msg, ())
        return CancelCommand()
    if kind == "namespace":
        _check_keys(msg, ("namespace",))
        return NamespaceCommand(normalize_namespace(msg.get("namespace", "")))
    if kind == "layers":
        _check_keys(msg, ("layers",))
        layers = msg.get("layers")
        if not isinstance(layers, list) or not all(isinstance(name, str) for name in layers):
            raise ProtocolError("'layers' must be a list of layer names")
        unknown = sorted(set(layers) - set(TOGGLE_LAYERS))
        if unknown:
            raise ProtocolError(f"unknown layer(s) {', '.join(unknown)}; known: {', '.join(TOGGLE_LAYERS)}")
        return LayersCommand(tuple(dict.fromkeys(layers)))
    if kind == "press":
        _check_keys(msg, ("button",))
        button = msg.get("button")
        if button not in PRESS_BUTTONS:
            raise ProtocolError(f"'button' must be one of {', '.join(PRESS_BUTTONS)}")
        return PressCommand(str(button))
    known = "initial_pose, goal, cancel, namespace, layers, press"
    raise ProtocolError(f"unknown message type {kind[:40]!r}; known: {known}")


class RateLimiter:
    """Token bucket: `rate` messages per second on average, bursts of `burst`. `allow()` spends one token."""

    def __init__(self, rate: float = 10.0, burst: float = 20.0, clock: Callable[[], float] = time.monotonic) -> None:
        if rate <= 0 or burst < 1:
            raise ValueError("rate must be positive and burst at least 1")
        self.rate = rate
        self.burst = burst
        self.clock = clock
        self._tokens = burst
        self._last = clock()
        self.rejected = 0

    def allow(self) -> bool:
        now = self.clock()
        self._tokens = min(self.burst, self._tokens + (now - self._last) * self.rate)
        self._last = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return True
        self.rejected += 1
        return False
