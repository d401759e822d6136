"""ManagedProcess stops its own process group, and never signals a process id after it has been reaped: the system
hands that id to the next process it starts, maybe another test's viewer (ids wrap at 32,768)."""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest

from tb4 import processes
from tb4.processes import ManagedProcess

pytestmark = pytest.mark.core


def _signals(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, int]]:
    sent: list[tuple[int, int]] = []
    real = os.killpg

    def killpg(pgid: int, sig: int) -> None:
        sent.append((pgid, sig))
        real(pgid, sig)

    monkeypatch.setattr(processes.os, "killpg", killpg)
    return sent


def test_a_process_that_ended_and_was_reaped_gets_no_signal_once_its_id_is_taken(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    proc = ManagedProcess([sys.executable, "-c", "pass"])
    assert proc.popen.wait(30) == 0
    sent = _signals(monkeypatch)
    monkeypatch.setattr(processes, "_pid_alive", lambda pid: pid == proc.pid)  # the id went to a newer process
    assert proc.stop() == 0
    assert proc.stop() == 0  # and a second stop, later, neither
    assert sent == []


def test_a_running_process_is_interrupted_first(monkeypatch: pytest.MonkeyPatch) -> None:
    proc = ManagedProcess([sys.executable, "-c", "import time; time.sleep(60)"])
    sent = _signals(monkeypatch)
    proc.stop(timeout=10)
    assert sent[0] == (proc.pid, signal.SIGINT)
    assert proc.popen.returncode is not None
    sent.clear()
    proc.stop()
    assert sent == [] or sent == [(proc.pid, signal.SIGKILL)]  # only its group's leftovers, while the id is free


def test_what_the_group_left_behind_is_killed(tmp_path: Path) -> None:
    marker = tmp_path / "child.pid"
    # the leader starts a child in its own group and exits at once
    code = (
        "import subprocess, sys; "
        f"c = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); "
        f"open({str(marker)!r}, 'w').write(str(c.pid))"
    )
    proc = ManagedProcess([sys.executable, "-c", code])
    assert proc.popen.wait(30) == 0
    child = int(marker.read_text())
    assert processes._pid_alive(child)
    proc.stop()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and _running(child):
        time.sleep(0.05)
    assert not _running(child)


def _running(pid: int) -> bool:
    """Alive and not a zombie (the child's parent has exited, so init reaps it)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"
