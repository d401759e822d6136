"""Mission processes forked from one that has imported everything they need: each is a new process (its own
globals, its own rclpy context and DDS participant, its own exit), without its start-up's imports.

A mission's process spends about a third of a second of CPU importing rclpy, the navigator and the messages (a
quarter of what a short trial of a sweep costs on its side). `python -m tb4.runner.fork_server FD MISSION [ARGS]`
imports what `python -m tb4.runner.tutorial_start MISSION` would (tutorial_start.preload), never initialises rclpy,
and then, for each request on the Unix socket FD, forks a child that runs tutorial_start.main as that process would:
in a session of its own, with the request's environment and folder, its output into the pipe passed with the
request, held at the start gate passed with it. The server is one thread (forking a threaded process copies locks
held by other threads); it reports each child's id when forked and its exit status when it ends (read from a pidfd:
at once). It ends at the end of its socket, and with the program that started it (end_with_parent); its children
end with it.

`ForkServer` is the starting side; `ForkedProcess` is what it gets for each child: the few methods of Popen that
tb4.runner.session.end_mission_process and a runner's loop use.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from typing import IO, Any

from tb4.core.waits import Deadline
from tb4.processes import PARENT_ENV, end_with_parent, exit_now

__all__ = ["ForkServer", "ForkedProcess", "serve"]

START_TIMEOUT = 60.0  # wall seconds for the server's imports on a loaded machine
REPLY_TIMEOUT = 10.0  # wall seconds for a fork's reply
_MESSAGE = 65536


class ForkedProcess:
    """A child of the fork server: its id (it leads its own process group), its output, its exit status.

    Attributes:
        pid: the child's id.
        stdout: the read end of its output (stdout and stderr).
        returncode: its exit status once known (negative: ended by that signal), else None.
    """

    def __init__(self, server: ForkServer, pid: int, stdout: IO[bytes]) -> None:
        self._server = server
        self.pid = pid
        self.stdout: IO[bytes] | None = stdout
        self.returncode: int | None = None

    def poll(self) -> int | None:
        """Its exit status, or None while it runs."""
        if self.returncode is None:
            self._server.pump(0.0)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for its end.

        Raises:
            subprocess.TimeoutExpired: it still runs after `timeout` seconds.
        """
        deadline = Deadline(timeout if timeout is not None else 1e9)
        while self.poll() is None:
            if deadline.expired:
                raise subprocess.TimeoutExpired(f"forked process {self.pid}", timeout or 0.0)
            self._server.pump(min(0.05, deadline.remaining()))
        assert self.returncode is not None
        return self.returncode


class ForkServer:
    """The fork server for one mission (the sweep side), started at once; `close` ends it.

    Args:
        child_args: the mission's tutorial_start arguments (tb4.runner.missions.Mission.child_args).
        env: the server's environment.
    """

    def __init__(self, child_args: Sequence[str], env: Mapping[str, str]) -> None:
        self._sock, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            self.process = subprocess.Popen(
                [sys.executable, "-m", "tb4.runner.fork_server", str(theirs.fileno()), *child_args],
                env={**env, PARENT_ENV: str(os.getpid())},
                pass_fds=(theirs.fileno(),),
                stdin=subprocess.DEVNULL,
                start_new_session=True,
            )
        finally:
            theirs.close()
        self._children: dict[int, ForkedProcess] = {}
        self._forked: list[int] = []
        self._ready = False

    def alive(self) -> bool:
        return self.process.poll() is None

    def spawn(self, argv: Sequence[str], env: Mapping[str, str], cwd: str, gate_fd: int) -> ForkedProcess:
        """A child running `tutorial_start.main(argv)` in `env` and `cwd`, held at the gate whose read end is
        `gate_fd` (passed to it; this process keeps its own copy).

        Raises:
            RuntimeError: the server ended, or did not fork within REPLY_TIMEOUT (START_TIMEOUT the first time).
        """
        read, write = os.pipe()
        try:
            request = json.dumps({"argv": list(argv), "env": dict(env), "cwd": cwd}).encode()
            try:
                socket.send_fds(self._sock, [request], [write, gate_fd])
            except OSError as exc:
                raise RuntimeError(f"the fork server ended ({exc})") from None
        finally:
            os.close(write)
        deadline = Deadline(REPLY_TIMEOUT if self._ready else START_TIMEOUT)
        while not self._forked:
            if deadline.expired or not self.alive():
                os.close(read)
                raise RuntimeError("the fork server " + ("ended" if not self.alive() else "did not answer"))
            self.pump(min(0.1, deadline.remaining()))
        self._ready = True
        pid = self._forked.pop(0)
        child = self._children[pid] = ForkedProcess(self, pid, os.fdopen(read, "rb", buffering=0))
        return child

    def pump(self, timeout: float) -> None:
        """Read the server's reports (forks, exits) for at most `timeout` seconds."""
        ready, _, _ = select.select([self._sock], [], [], max(timeout, 0.0))
        while ready:
            try:
                data = self._sock.recv(_MESSAGE, socket.MSG_DONTWAIT)
            except BlockingIOError:
                return
            except OSError:
                data = b""
            if not data:
                for child in self._children.values():  # the server is gone, and its children with it
                    if child.returncode is None:
                        child.returncode = -signal.SIGKILL
                return
            kind, *values = data.decode().split()
            if kind == "forked":
                self._forked.append(int(values[0]))
            elif kind == "exit":
                ended = self._children.pop(int(values[0]), None)
                if ended is not None:
                    ended.returncode = int(values[1])

    def close(self) -> None:
        """End the server (the end of its socket) and, by their ids, any child still running."""
        for child in list(self._children.values()):
            if child.returncode is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(child.pid, signal.SIGKILL)
        self._sock.close()
        try:
            self.process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait(timeout=5.0)


# --------------------------------------------------------------------------------------------------- the server
def _child(sock: socket.socket, request: dict[str, Any], output: int, gate: int) -> None:
    """In the forked child: become the mission's process, run it, exit with its status."""
    from tb4.runner import tutorial_start

    sock.close()
    os.setsid()
    os.dup2(output, 1)
    os.dup2(output, 2)
    os.close(output)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.environ.clear()
    os.environ.update(request["env"])
    os.environ[PARENT_ENV] = str(os.getppid())  # the server: it ends with the sweep, and its children with it
    os.environ[tutorial_start.GATE_ENV] = str(gate)
    os.chdir(request["cwd"])
    argv = list(request["argv"])
    script = argv[:1] in (["--script"], ["--module"])
    try:
        code = tutorial_start.main(argv)
    except SystemExit as exc:
        code = tutorial_start.exit_status(exc.code)
    except BaseException:  # noqa: BLE001 - printed as Python would, exit 1
        import traceback

        traceback.print_exc()
        code = 1
    if script:  # a user's mission may register atexit handlers: Python's own exit would run them
        with contextlib.suppress(Exception):
            atexit._run_exitfuncs()
    exit_now(code)


def serve(fd: int, child_args: Sequence[str]) -> int:
    """The server's loop (see the module): fork a child per request, report forks and exits, until the socket
    ends."""
    from tb4.runner import tutorial_start

    end_with_parent()
    tutorial_start.preload(list(child_args))
    # what is loaded now is shared with every child: kept out of the collector's scans, its pages stay shared
    # instead of being copied into each child when a collection there touches them
    gc.collect()
    gc.freeze()
    sock = socket.socket(fileno=fd)
    children: dict[int, int] = {}  # pidfd -> pid
    try:
        while True:
            waiting: list[Any] = [sock, *children]
            ready, _, _ = select.select(waiting, [], [])
            for pidfd in [r for r in ready if r in children]:
                pid = children.pop(pidfd)
                os.close(pidfd)
                _, status = os.waitpid(pid, 0)
                sock.send(f"exit {pid} {os.waitstatus_to_exitcode(status)}".encode())
            if sock not in ready:
                continue
            message, fds, _flags, _addr = socket.recv_fds(sock, _MESSAGE, 2)
            if not message:
                return 0
            if len(fds) != 2:
                for extra in fds:
                    os.close(extra)
                continue
            output, gate = fds
            pid = os.fork()
            if pid == 0:
                _child(sock, json.loads(message), output, gate)
            os.close(output)
            os.close(gate)
            children[os.pidfd_open(pid)] = pid
            sock.send(f"forked {pid}".encode())
    except (KeyboardInterrupt, BrokenPipeError, ConnectionResetError):
        return 0
    finally:
        for pid in children.values():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(pid, signal.SIGINT)
        time.sleep(0)


if __name__ == "__main__":
    sys.exit(serve(int(sys.argv[1]), sys.argv[2:]))
