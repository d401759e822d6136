"""`tb4 run` starts the tutorial's process while the simulator boots; the process waits at a start gate (a pipe)
until the runner opens it, and ends without running when the runner closes it instead."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from tb4.runner.tutorial_start import GATE_ENV, StartGate, wait_at_start_gate

pytestmark = pytest.mark.core

WAITER = "import sys; from tb4.runner.tutorial_start import wait_at_start_gate; print(wait_at_start_gate({t}))"


def _spawn(args: list[str], gate: StartGate) -> subprocess.Popen[str]:
    return gate.spawn(args, os.environ, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_the_child_waits_until_the_gate_opens() -> None:
    gate = StartGate()
    child = _spawn([sys.executable, "-c", WAITER.format(t=60)], gate)
    try:
        time.sleep(0.5)
        assert child.poll() is None, "the child must wait at the gate"
        gate.open()
        out, _ = child.communicate(timeout=30)
        assert out.strip() == "True"
    finally:
        gate.close()
        child.kill()
        child.wait(timeout=10)


def test_a_closed_gate_or_a_timeout_says_false() -> None:
    gate = StartGate()
    child = _spawn([sys.executable, "-c", WAITER.format(t=60)], gate)
    gate.close()
    out, _ = child.communicate(timeout=30)
    assert out.strip() == "False"
    gate = StartGate()
    child = _spawn([sys.executable, "-c", WAITER.format(t=0.2)], gate)
    try:
        out, _ = child.communicate(timeout=30)
        assert out.strip() == "False"
    finally:
        gate.close()


def test_without_a_gate_nothing_waits(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(GATE_ENV, raising=False)
    start = time.monotonic()
    assert wait_at_start_gate(timeout=30)
    assert time.monotonic() - start < 5


def test_the_tutorial_runs_with_its_arguments_once_the_gate_opens() -> None:
    gate = StartGate()
    args = [sys.executable, "-m", "tb4.runner.tutorial_start", "nav_to_pose", "--help"]
    child = _spawn(args, gate)
    try:
        gate.open()
        out, _ = child.communicate(timeout=60)
        assert child.returncode == 0
        assert "Navigate to one pose" in out and "--namespace" in out  # the tutorial's own argparse help
    finally:
        gate.close()
        child.kill()
        child.wait(timeout=10)


def test_a_tutorial_whose_gate_closes_ends_without_running() -> None:
    gate = StartGate()
    args = [sys.executable, "-m", "tb4.runner.tutorial_start", "nav_to_pose", "--help"]
    child = _spawn(args, gate)
    gate.close()
    out, _ = child.communicate(timeout=60)
    assert child.returncode == 1
    assert "did not start the simulator" in out and "Navigate to one pose" not in out


def test_an_unknown_tutorial_is_named_in_the_error() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "tb4.runner.tutorial_start", "nav_to_posse"], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2
    assert "no tutorial named 'nav_to_posse'" in result.stderr and "nav_to_pose" in result.stderr


@pytest.mark.parametrize("value", ["not-a-number", "987654"])
def test_a_gate_that_is_not_an_open_pipe_is_a_clear_error(value: str) -> None:
    result = subprocess.run(
        [sys.executable, "-m", "tb4.runner.tutorial_start", "nav_to_pose"],
        env={**os.environ, GATE_ENV: value},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert f"{GATE_ENV}={value!r} is not an open pipe" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("ros_args", [False, True])
def test_rclpy_is_initialised_before_the_gate_unless_the_tutorial_takes_ros_arguments(
    monkeypatch: pytest.MonkeyPatch, ros_args: bool
) -> None:
    """The tutorial's DDS participant is made before the gate, so that it finds the simulator while it boots; a
    tutorial given --ros-args initialises rclpy with them itself (an earlier init would make it skip them)."""
    import importlib
    from types import SimpleNamespace

    import rclpy

    from tb4.runner import tutorial_start

    events: list[str] = []
    tutorial = SimpleNamespace(main=lambda args: events.append(f"main {' '.join(args)}") or 0)
    real_import = importlib.import_module
    monkeypatch.setattr(
        tutorial_start.importlib,
        "import_module",
        lambda name: tutorial if name == "tb4.tutorials.nav_to_pose" else real_import(name),
    )
    monkeypatch.setattr(rclpy, "init", lambda *a, **k: events.append("init"))
    monkeypatch.setattr(tutorial_start, "wait_at_start_gate", lambda: events.append("gate") or True)
    monkeypatch.setattr(sys, "argv", list(sys.argv))  # main sets the tutorial's argv
    args = ["--ros-args", "-p", "x:=1"] if ros_args else ["--laps", "1"]
    assert tutorial_start.main(["nav_to_pose", *args]) == 0
    expected = ["gate", f"main {' '.join(args)}"]
    assert events == (expected if ros_args else ["init", *expected])


PRELOADED = """
from nav2_msgs.action import NavigateToPose
from rcl_interfaces.msg import ParameterEvent
from tb4.runner.tutorial_start import preload
preload(["nav_to_pose"])
print(*(type(t)._TYPE_SUPPORT is not None for t in (NavigateToPose, ParameterEvent)))
"""


def test_preload_loads_the_type_supports_a_forked_mission_would_load_itself() -> None:
    """A mission forked after `preload` finds the navigator's and rclpy's own interfaces' type supports loaded (no
    shared library and no rosidl parser loaded inside its first publisher or client)."""
    done = subprocess.run([sys.executable, "-c", PRELOADED], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["True", "True"], done.stdout


WARMED = """
import inspect
from tb4.runner.tutorial_start import preload
print("tb4.tutorials.nav_to_pose" in getattr(inspect, "_filesbymodname", {}))
preload(["nav_to_pose"])
print("tb4.tutorials.nav_to_pose" in getattr(inspect, "_filesbymodname", {}))
"""


def test_preload_makes_the_map_of_modules_to_files_rclpys_first_log_line_would_make() -> None:
    """rclpy's logger names each call's caller with `inspect`, whose first lookup maps every loaded module to its
    file: made in the fork server before it forks, not again in each mission's first log line."""
    done = subprocess.run([sys.executable, "-c", WARMED], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["False", "True"], done.stdout
