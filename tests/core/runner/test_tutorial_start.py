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
