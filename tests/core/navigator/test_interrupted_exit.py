"""A script that SIGINT ends through the navigator's handler exits as Python's own Ctrl-C would: killed by SIGINT.

CPython ends a process whose main module left a KeyboardInterrupt uncaught by killing itself with SIGINT, unless a
thread ran a string eval or exec in the meantime (making a dataclass or a namedtuple does): the status is then 1.
A navigator's spin threads run callbacks while the exit handlers wait for them; stress run 32 saw status 1.
These scripts build no ROS node: the handler is the one `watch_signals` installs, set directly.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("rclpy", reason="ROS wheels not installed")

pytestmark = pytest.mark.core

SCRIPT = """
import atexit, os, signal, threading, time
from tb4.navigator import _signals

signal.signal(signal.SIGINT, _signals._on_signal)

def making_classes():
    while True:
        eval("1")  # what a dataclass or namedtuple being made does: a string compiled and run
        time.sleep(0.005)

threading.Thread(target=making_classes, daemon=True).start()
atexit.register(time.sleep, 0.3)  # an exit handler's wait (a spin thread's join), while that thread runs
{body}
"""

SIGNAL_ITSELF = "os.kill(os.getpid(), signal.SIGINT)\ntime.sleep(10)\n"
CAUGHT = """
try:
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(10)
except KeyboardInterrupt:
    print("caught")
"""


def run(body: str) -> subprocess.CompletedProcess[str]:
    code = textwrap.dedent(SCRIPT).format(body=body)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)


def test_an_uncaught_keyboard_interrupt_from_sigint_ends_the_process_killed_by_sigint() -> None:
    done = run(SIGNAL_ITSELF)
    assert done.returncode == -signal.SIGINT, done.stderr
    assert "KeyboardInterrupt" in done.stderr  # the traceback Python prints, as before


def test_a_caught_keyboard_interrupt_leaves_the_exit_status_to_the_script() -> None:
    done = run(CAUGHT)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "caught"


def test_an_uncaught_error_after_a_caught_interrupt_exits_with_status_1() -> None:
    done = run(CAUGHT + "raise RuntimeError('after the interrupt')\n")
    assert done.returncode == 1, done.stderr
    assert "RuntimeError: after the interrupt" in done.stderr
