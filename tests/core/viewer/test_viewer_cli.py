"""`tb4 view` arguments: checked by the parser, before any ROS node or socket exists."""

from __future__ import annotations

import argparse

import pytest

from tb4.cli import cmd_view


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tb4")
    cmd_view.register(parser.add_subparsers(dest="command"))
    return parser


def test_defaults_serve_this_machine_only() -> None:
    args = _parser().parse_args(["view"])
    assert (args.host, args.port, args.namespace, args.world) == ("127.0.0.1", cmd_view.DEFAULT_PORT, "", None)
    args = _parser().parse_args(["view", "--port", "0", "--namespace", "robot1/", "--host", "0.0.0.0"])
    assert (args.port, args.namespace, args.host) == (0, "/robot1", "0.0.0.0")


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["view", "--port", "70000"], "between 0 and 65535"),
        (["view", "--port", "http"], "port must be a number"),
        (["view", "--namespace", "robot 1"], "invalid namespace"),
    ],
)
def test_bad_arguments_are_refused_with_a_reason(argv: list[str], message: str, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        _parser().parse_args(argv)
    assert exc.value.code == 2
    assert message in capsys.readouterr().err
