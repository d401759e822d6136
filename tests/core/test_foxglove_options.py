"""`--foxglove [PORT]`, `--foxglove-host` and `--foxglove-allow-remote` on `tb4 sim` and `tb4 run`: loopback unless
the user asks otherwise twice, clear refusals, and the missing extra named with its pip command."""

from __future__ import annotations

import argparse
import importlib.util

import pytest

from tb4.cli.main import build_parser
from tb4.extras import MissingExtraError
from tb4.foxglove import DEFAULT_HOST, DEFAULT_PORT, FoxgloveOptions, add_foxglove_arguments, foxglove_options

pytestmark = pytest.mark.core


def _options(*argv: str) -> FoxgloveOptions | None:
    parser = argparse.ArgumentParser()
    add_foxglove_arguments(parser)
    return foxglove_options(parser.parse_args(list(argv)))


def test_without_the_option_nothing_is_served() -> None:
    assert _options() is None


def test_the_option_alone_serves_on_loopback_at_the_apps_default_port() -> None:
    assert _options("--foxglove") == FoxgloveOptions(DEFAULT_PORT, DEFAULT_HOST) == FoxgloveOptions(8765, "127.0.0.1")
    assert _options("--foxglove", "9001") == FoxgloveOptions(9001, "127.0.0.1")
    assert _options("--foxglove", "0") == FoxgloveOptions(0, "127.0.0.1")  # any free port
    for loopback in ("localhost", "127.0.0.2", "::1"):
        assert _options("--foxglove", "--foxglove-host", loopback) == FoxgloveOptions(8765, loopback)


@pytest.mark.parametrize("port", ["-1", "65536", "http", "8765.5"])
def test_a_port_that_is_no_port_is_refused_by_the_parser(port: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        _options("--foxglove", port)
    assert "the Foxglove port must be a number between 0 and 65535" in capsys.readouterr().err


@pytest.mark.parametrize("host", ["0.0.0.0", "::", "192.168.1.20", "robot.example"])
def test_an_address_beyond_loopback_needs_the_second_option(host: str) -> None:
    with pytest.raises(ValueError, match="--foxglove-allow-remote") as refused:
        _options("--foxglove", "--foxglove-host", host)
    assert "checks no Host, Origin or token" in str(refused.value)
    assert _options("--foxglove", "--foxglove-host", host, "--foxglove-allow-remote") == FoxgloveOptions(8765, host)


def test_the_host_options_without_foxglove_are_a_mistake_said_as_such() -> None:
    with pytest.raises(ValueError, match="need --foxglove"):
        _options("--foxglove-host", "localhost")
    with pytest.raises(ValueError, match="need --foxglove"):
        _options("--foxglove-allow-remote")
    with pytest.raises(ValueError, match="must name an address"):
        _options("--foxglove", "--foxglove-host", " ")


@pytest.mark.parametrize("command", [["sim"], ["run", "nav_to_pose"]])
def test_tb4_sim_and_tb4_run_take_the_options(command: list[str]) -> None:
    args = build_parser().parse_args([*command, "--foxglove", "8800"])
    assert foxglove_options(args) == FoxgloveOptions(8800, "127.0.0.1")
    assert foxglove_options(build_parser().parse_args(command)) is None


def test_tb4_sim_refuses_the_viewers_port_for_foxglove(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from tb4.cli import cmd_sim
    from tb4.cli.main import main

    monkeypatch.setattr(cmd_sim, "apply_simulator_dds_profile", lambda: None)  # this process's environment stays
    assert main(["sim", "--view", "--foxglove"]) == 2
    assert "--view and --foxglove both want port 8765" in capsys.readouterr().out


def test_a_missing_extra_names_the_pip_command(monkeypatch: pytest.MonkeyPatch) -> None:
    from tb4.foxglove import live

    real = importlib.util.find_spec
    monkeypatch.setattr(live.importlib.util, "find_spec", lambda name, *a: None if name == "foxglove" else real(name))
    with pytest.raises(MissingExtraError, match=r"pip install 'turtlebot4-navigator\[foxglove\]'"):
        live.require_foxglove()
