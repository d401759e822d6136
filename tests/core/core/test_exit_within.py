"""exit_within ends a process whose teardown is stuck, even in C with the GIL held, and says where it was: the
bound the simulator puts on its ROS teardown once its run is finished."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

import pytest

pytestmark = pytest.mark.core

#: a teardown stuck in C without releasing the GIL (a PyDLL call keeps it): no Python thread runs meanwhile
STUCK_CHILD = textwrap.dedent(
    """
    import ctypes
    from tb4.processes import exit_within

    def stuck_teardown():
        ctypes.PyDLL(None).sleep(60)

    exit_within({bound})
    stuck_teardown()
    """
)


def _run(child: str) -> tuple[subprocess.CompletedProcess[str], float]:
    """Run `child` (Python source) with a 30 s bound; its result and its wall time."""
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-c", child], capture_output=True, text=True, timeout=30)
    return done, time.monotonic() - started


def test_a_teardown_stuck_in_c_with_the_gil_held_ends_at_the_bound_with_its_stack() -> None:
    done, elapsed = _run(STUCK_CHILD.format(bound=0.5))
    assert done.returncode == 1, done
    assert elapsed < 20, elapsed  # the child sleeps 60 s unless ended
    assert "Timeout (0:00:00" in done.stderr, done.stderr
    assert "in stuck_teardown" in done.stderr, done.stderr


def test_a_later_call_replaces_the_bound() -> None:
    child = STUCK_CHILD.replace("exit_within({bound})", "exit_within(60)\nexit_within({bound})")
    done, elapsed = _run(child.format(bound=0.5))
    assert done.returncode == 1 and "in stuck_teardown" in done.stderr, done
    assert elapsed < 20, elapsed


def test_a_process_that_ends_in_time_keeps_its_own_status() -> None:
    done, _ = _run("import sys; from tb4.processes import exit_within; exit_within(30); sys.exit(3)")
    assert done.returncode == 3, done
    assert "Timeout" not in done.stderr
