"""ManagedProcess stops its own process group, and never signals a process id after it has been reaped: the system
hands that id to the next process it starts, maybe another test's viewer (ids wrap at 32,768)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tb4 import processes
from tb4.core.waits import wait_until
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


# --- a child ends with the process that started it (end_with_parent) ------------------------------------------
# The parent: starts CHILD with ManagedProcess, prints its id, then waits to be killed.
PARENT = """
import signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)  # as a background job of a script (make test): the child inherits it
from tb4.processes import ManagedProcess
child = ManagedProcess([sys.executable, "-c", sys.argv[1]], log_path=__import__("pathlib").Path(sys.argv[2]))
print(child.pid, flush=True)
time.sleep(60)
"""
# The child: a tb4 program's first step, then it says what its own children would inherit, and waits.
CHILD = """
import os, signal, sys, time
import tb4.processes as p
p.end_with_parent()
if os.environ.get("CHILD_IGNORES_SIGINT"):  # a handler of its own that does not end it
    signal.signal(signal.SIGINT, lambda *_: None)
    p.PARENT_GONE_GRACE = 0.5
print("inherited:", os.environ.get(p.PARENT_ENV), flush=True)
try:
    time.sleep(60)
except KeyboardInterrupt:
    print("interrupted", flush=True)
"""


def _orphan(tmp_path: Path, extra_env: dict[str, str] | None = None) -> tuple[int, Path]:
    """Start PARENT (which starts CHILD), kill the parent hard once the child is up; the child's id and log."""
    log = tmp_path / "child.log"
    env = {**os.environ, **(extra_env or {})}
    parent = subprocess.Popen(
        [sys.executable, "-c", PARENT, CHILD, str(log)],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        assert parent.stdout is not None
        child = int(parent.stdout.readline())
        assert wait_until(lambda: "inherited:" in (log.read_text() if log.exists() else ""), 30)
    finally:
        parent.kill()
        parent.wait(10)
    return child, log


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as handle:
            return handle.read().split()[2] == "Z"  # a zombie of init's has ended
    except FileNotFoundError:
        return True


def test_a_child_is_interrupted_once_the_process_that_started_it_is_killed(tmp_path: Path) -> None:
    child, log = _orphan(tmp_path)
    try:
        assert wait_until(lambda: _gone(child), 10), "the child outlived its parent"
        assert log.read_text().splitlines() == ["inherited: None", "interrupted"]  # SIGINT: a clean shutdown
    finally:
        if not _gone(child):
            os.kill(child, signal.SIGKILL)


def test_a_child_that_ignores_the_interrupt_is_killed_after_the_grace(tmp_path: Path) -> None:
    child, log = _orphan(tmp_path, {"CHILD_IGNORES_SIGINT": "1"})
    try:
        assert wait_until(lambda: _gone(child), 10), "the child outlived its parent"
        assert "interrupted" not in log.read_text()
    finally:
        if not _gone(child):
            os.kill(child, signal.SIGKILL)


def test_a_bad_parent_variable_is_a_warning(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv(processes.PARENT_ENV, "not-a-pid")
    processes.end_with_parent()
    assert "ignoring TB4_END_WITH_PARENT='not-a-pid': not a process id" in capsys.readouterr().err
    assert processes.PARENT_ENV not in os.environ


# --- exit_now: no interpreter finalization, output kept, shared-memory files cleaned ------------------------------
def test_exit_now_keeps_unflushed_output_and_the_exit_code(tmp_path: Path) -> None:
    code = "import sys; from tb4.processes import exit_now; print('out', end=''); sys.stderr.write('e'); exit_now(3)"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert (done.returncode, done.stdout, done.stderr) == (3, "out", "e")


def test_exit_now_has_the_shared_memory_files_left_behind_removed(tmp_path: Path) -> None:
    """A Fast DDS participant's files stay when its process skips finalization; a detached cleaner removes the
    ones that appeared after the snapshot, once the process has gone (here a stand-in file)."""
    name = f"fastdds_tb4test_{os.getpid()}_{time.monotonic_ns()}"
    code = (
        "import sys; from pathlib import Path; from tb4.processes import SHM_DIR, exit_now, shm_snapshot\n"
        "before = shm_snapshot()\n"
        f"(SHM_DIR / {name!r}).write_bytes(b'x')\n"
        "exit_now(0, before)\n"
    )
    leftover = processes.SHM_DIR / name
    try:
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr
        assert wait_until(lambda: not leftover.exists(), 30), "the cleaner did not remove the file"
    finally:
        leftover.unlink(missing_ok=True)


def test_a_hung_python_child_is_ended_saying_where_each_thread_was(tmp_path: Path) -> None:
    program = (
        "import threading, time\n"
        "def helper_waits_here():\n"
        "    threading.Event().wait()\n"
        "def main_thread_waits_here():\n"
        "    print('ready', flush=True)\n"
        "    time.sleep(60)\n"
        "threading.Thread(target=helper_waits_here, daemon=True).start()\n"
        "main_thread_waits_here()\n"
    )
    env = {**os.environ, "PYTHONFAULTHANDLER": "1"}
    proc = ManagedProcess([sys.executable, "-c", program], env=env, log_path=tmp_path / "hung.log")
    try:
        assert proc.wait_for_output("ready", timeout=20.0), proc.output()
        started = time.monotonic()
        proc.abort_showing_stacks()
        assert time.monotonic() - started < 5.0
    finally:
        proc.stop()
    assert not proc.alive() and proc.popen.returncode == -signal.SIGABRT
    output = proc.output()
    assert "in main_thread_waits_here" in output and "in helper_waits_here" in output, output
