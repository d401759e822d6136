"""What the page may send: every malformed or hostile message is rejected with a reason, valid ones parse."""

from __future__ import annotations

import json
import math

import pytest

from tb4.viewer.protocol import (
    MAX_MESSAGE_BYTES,
    CancelCommand,
    LayersCommand,
    NamespaceCommand,
    PoseCommand,
    ProtocolError,
    RateLimiter,
    normalize_namespace,
    parse_message,
)


def test_pose_tools_parse_to_commands_with_wrapped_yaw() -> None:
    cmd = parse_message(json.dumps({"type": "initial_pose", "x": 1.5, "y": -2, "yaw": 3 * math.pi / 2}))
    assert isinstance(cmd, PoseCommand) and cmd.kind == "initial_pose"
    assert (cmd.x, cmd.y) == (1.5, -2.0)
    assert cmd.yaw == pytest.approx(-math.pi / 2)
    goal = parse_message('{"type": "goal", "x": 0, "y": 0, "yaw": 0}')
    assert goal == PoseCommand("goal", 0.0, 0.0, 0.0)


def test_other_commands_parse() -> None:
    assert parse_message('{"type": "cancel"}') == CancelCommand()
    assert parse_message('{"type": "namespace", "namespace": "/robot1/"}') == NamespaceCommand("/robot1")
    assert parse_message('{"type": "namespace", "namespace": ""}') == NamespaceCommand("")
    layers = parse_message('{"type": "layers", "layers": ["local_costmap", "local_costmap"]}')
    assert layers == LayersCommand(("local_costmap",))


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("not json", "not JSON"),
        ("[1, 2]", "JSON object"),
        ('{"x": 1}', "'type'"),
        ('{"type": 7}', "'type'"),
        ('{"type": "teleport"}', "unknown message type"),
        ('{"type": "goal", "x": NaN, "y": 0, "yaw": 0}', "finite"),
        ('{"type": "goal", "x": 0, "y": Infinity, "yaw": 0}', "finite"),
        ('{"type": "goal", "x": 0, "y": -Infinity, "yaw": 0}', "finite"),
        ('{"type": "goal", "x": "1", "y": 0, "yaw": 0}', "must be a number"),
        ('{"type": "goal", "x": true, "y": 0, "yaw": 0}', "must be a number"),
        ('{"type": "goal", "x": null, "y": 0, "yaw": 0}', "must be a number"),
        ('{"type": "goal", "x": 0, "y": 0}', "needs a number 'yaw'"),
        ('{"type": "goal", "x": 1e9, "y": 0, "yaw": 0}', "out of range"),
        ('{"type": "initial_pose", "x": 0, "y": 0, "yaw": 0, "z": 1}', "unexpected field"),
        ('{"type": "cancel", "all": true}', "unexpected field"),
        ('{"type": "namespace", "namespace": "robot 1"}', "invalid namespace"),
        ('{"type": "namespace", "namespace": "../etc"}', "invalid namespace"),
        ('{"type": "namespace", "namespace": 5}', "must be a string"),
        ('{"type": "layers", "layers": "map"}', "list"),
        ('{"type": "layers", "layers": ["everything"]}', "unknown layer"),
        ("[" * 100000, "too long"),
        ("[" * 3000 + "]" * 3000, "too long"),
    ],
)
def test_malformed_messages_are_rejected_with_a_reason(text: str, reason: str) -> None:
    with pytest.raises(ProtocolError, match=reason):
        parse_message(text)


def test_deeply_nested_json_within_the_size_limit_is_rejected_not_crashing() -> None:
    text = "[" * (MAX_MESSAGE_BYTES // 2 - 1) + "]" * (MAX_MESSAGE_BYTES // 2 - 1)
    with pytest.raises(ProtocolError):
        parse_message(text)


def test_binary_frames_are_rejected() -> None:
    with pytest.raises(ProtocolError, match="binary"):
        parse_message(b'{"type": "cancel"}')


def test_namespace_normalization() -> None:
    assert normalize_namespace(" /robot1 ") == "/robot1"
    assert normalize_namespace("fleet/robot_2") == "/fleet/robot_2"
    with pytest.raises(ProtocolError):
        normalize_namespace("r" * 101)
    with pytest.raises(ProtocolError):
        normalize_namespace("rôbot")


class FakeClock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_rate_limiter_allows_bursts_then_the_average_rate() -> None:
    clock = FakeClock()
    limiter = RateLimiter(rate=10.0, burst=5.0, clock=clock)
    assert [limiter.allow() for _ in range(7)] == [True] * 5 + [False] * 2
    assert limiter.rejected == 2
    clock.now = 0.1  # one token back
    assert limiter.allow() and not limiter.allow()
    clock.now = 100.0  # refills only up to the burst
    assert sum(limiter.allow() for _ in range(50)) == 5


def test_rate_limiter_checks_its_parameters() -> None:
    with pytest.raises(ValueError):
        RateLimiter(rate=0)
    with pytest.raises(ValueError):
        RateLimiter(burst=0.5)
