"""The tutorial's process under `tb4 run`: started while the simulator boots, held at a start gate until it is up.

A tutorial's process spends about a second importing rclpy, the navigator and the messages before its first ROS
call. `tb4 run` starts it together with the simulator, so that second overlaps the simulator's boot, and opens the
gate (one byte down a pipe) once the simulator is ready, so the tutorial's first call still finds the robot up, as
when it was started afterwards. If `tb4 run` gives up instead (the simulator did not start), it closes the pipe and
the tutorial ends without having sent anything.

`python -m tb4.runner.tutorial_start NAME [ARGS]` is that process: import, wait at the gate, then the tutorial's
`main(ARGS)`. A user's mission runs the same way: `--script PATH [ARGS]` runs the file as `python PATH ARGS` would
(as `__main__`, its folder first on sys.path), `--module NAME --path DIR [ARGS]` as `python -m NAME ARGS` from DIR.
Its exit code is the process's own; an exception it raises prints its traceback and exits with 1, as Python does.
A user's script initialises rclpy itself, so only the imports are done ahead for it.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import re
import select
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

from tb4.processes import PARENT_ENV, end_with_parent, exit_now

__all__ = [
    "StartGate",
    "wait_at_start_gate",
    "preload",
    "load_type_supports",
    "warm_logging",
    "main",
    "exit_status",
    "GATE_ENV",
    "GATE_TIMEOUT",
]

T = TypeVar("T")
GATE_ENV = "TB4_RUN_START_GATE_FD"
#: s: the longest a tutorial waits at the gate; `tb4 run` opens or closes it well before (it waits 60 s for the
#: simulator and 10 s for a recorder), so this only bounds a runner that hangs
GATE_TIMEOUT = 180.0
_OPEN = b"1"


class StartGate:
    """The runner's side: `spawn()` the child held at the gate, then `open()` or `close()`."""

    def __init__(self) -> None:
        self._read, self._write = os.pipe()

    def spawn(self, args: Sequence[str], env: Mapping[str, str], **popen: Any) -> subprocess.Popen[Any]:
        """Popen(args) with the gate's read end passed down and named in the child's environment (and this
        process named as its parent: `end_with_parent`)."""
        try:
            env = {**env, GATE_ENV: str(self._read), PARENT_ENV: str(os.getpid())}
            return subprocess.Popen(args, env=env, pass_fds=(self._read,), **popen)
        finally:
            self._started()

    def hand_over(self, start: Callable[[int], T]) -> T:
        """`start(fd)` starts the child some other way (tb4.runner.fork_server), given the gate's read end, which
        it passes on; this process's copy is closed after.

        Args:
            start: starts the child with the read end.

        Returns:
            What `start` returned.
        """
        try:
            return start(self._read)
        finally:
            self._started()

    def _started(self) -> None:
        """The child holds its own copy of the read end now (or there is no child)."""
        if self._read >= 0:
            os.close(self._read)
            self._read = -1

    def open(self) -> None:
        if self._write >= 0:
            with contextlib.suppress(BrokenPipeError):  # the tutorial has ended already: its exit code says why
                os.write(self._write, _OPEN)
        self.close()

    def close(self) -> None:
        self._started()
        if self._write >= 0:
            os.close(self._write)
            self._write = -1


def wait_at_start_gate(timeout: float = GATE_TIMEOUT) -> bool:
    """Block until the runner opens the gate (True); False when it closed it or `timeout` passed. Returns True at
    once in a process that has no gate (a tutorial run by hand)."""
    fd_text = os.environ.pop(GATE_ENV, None)
    if fd_text is None:
        return True
    try:
        fd = int(fd_text)
        ready, _, _ = select.select([fd], [], [], timeout)
    except (ValueError, OSError) as exc:
        raise RuntimeError(f"{GATE_ENV}={fd_text!r} is not an open pipe ({exc})") from None
    try:
        return bool(ready) and os.read(fd, 1) == _OPEN
    finally:
        os.close(fd)


USAGE = "usage: python -m tb4.runner.tutorial_start NAME|--script PATH|--module NAME --path DIR [ARGS]"


def exit_status(code: object) -> int:
    """What `sys.exit(code)` makes the interpreter's exit status: None 0, an int itself, anything else printed, 1.

    Args:
        code: what the program passed to sys.exit.

    Returns:
        The exit status.
    """
    if code is None:
        return 0
    if isinstance(code, int):
        return code
    print(code, file=sys.stderr)
    return 1


def run_user_mission(kind: str, target: str, args: list[str], search_path: str = "") -> int:
    """Wait at the gate, then run a user's script or module as Python would; its exit status."""
    import runpy
    import traceback

    import rclpy  # noqa: F401 - imported ahead, while the simulator boots

    import tb4.navigator  # noqa: F401 - the same (nav2_simple_commander and turtlebot4_navigation import it)

    try:
        opened = wait_at_start_gate()
    except RuntimeError as exc:
        print(f"{target}: {exc}", file=sys.stderr)
        return 2
    if not opened:
        print(f"{target}: tb4 run did not start the simulator; the mission does not run", file=sys.stderr)
        return 1
    try:
        if kind == "--script":
            sys.argv = [target, *args]
            sys.path.insert(0, os.path.dirname(target))
            runpy.run_path(target, run_name="__main__")
        else:
            sys.argv = [target, *args]
            sys.path.insert(0, search_path or os.getcwd())
            runpy.run_module(target, run_name="__main__", alter_sys=True)
    except SystemExit as exc:
        return exit_status(exc.code)
    except KeyboardInterrupt:
        traceback.print_exc()
        return 130
    except BaseException:  # noqa: BLE001 - the user's exception: print it as Python would, exit 1
        traceback.print_exc()
        return 1
    return 0


def preload(argv: Sequence[str]) -> None:
    """Import what `main(argv)` runs (rclpy, the navigator, a tutorial's module) without starting anything: what
    tb4.runner.fork_server does once for the processes it forks.

    Args:
        argv: the arguments `main` will get.
    """
    import rclpy  # noqa: F401

    import tb4.navigator  # noqa: F401

    if argv and not argv[0].startswith("--"):
        from tb4.tutorials import TUTORIALS

        if argv[0] in TUTORIALS:
            importlib.import_module(f"tb4.tutorials.{argv[0]}")
    load_type_supports()
    from tb4.ros.background import events_executor_complete

    events_executor_complete()  # the navigator's choice of executor, decided once for every process forked after
    warm_logging()


def warm_logging() -> None:
    """Do once what rclpy's logger does at its first call in a process: it names each call's caller with `inspect`,
    whose first lookup maps every loaded module to its file (a realpath of each of hundreds). Done before the fork
    server forks, every mission's first log line finds that map made."""
    with contextlib.suppress(Exception):  # an rclpy without it: the first log line pays, as before
        from rclpy.impl.rcutils_logger import CallerId

        CallerId()


#: a module of generated ROS interfaces: pkg.msg._name, pkg.srv._name, pkg.action._name
_INTERFACE_MODULE = re.compile(r"^\w+\.(msg|srv|action)\._\w+$")


def load_type_supports() -> int:
    """Load the C type support of every ROS interface imported so far, as rclpy does on a type's first publisher,
    subscription or client. Each package's type support is a shared library, and rclpy loads it (and, the first
    time, rosidl's parser) inside the first call that uses one of its types: a mission forked after this creates
    its node and clients without those loads, which are most of what its navigator's construction costs.

    Returns:
        How many interface types were loaded.
    """
    from rclpy.type_support import check_for_type_support

    loaded = 0
    for name, module in list(sys.modules.items()):
        if module is None or not _INTERFACE_MODULE.match(name):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, type) and hasattr(type(value), "__import_type_support__"):
                with contextlib.suppress(Exception):  # a type that cannot load fails where it is used, as before
                    check_for_type_support(value)
                    loaded += 1
    return loaded


def main(argv: Sequence[str]) -> int:
    if not argv:
        print(USAGE, file=sys.stderr)
        return 2
    end_with_parent()  # a `tb4 run` that died must not leave its tutorial driving the robot
    if argv[0] == "--script" and len(argv) >= 2:
        return run_user_mission("--script", argv[1], list(argv[2:]))
    if argv[0] == "--module" and len(argv) >= 4 and argv[2] == "--path":
        return run_user_mission("--module", argv[1], list(argv[4:]), argv[3])
    if argv[0].startswith("--"):
        print(USAGE, file=sys.stderr)
        return 2
    name, args = argv[0], list(argv[1:])
    from tb4.tutorials import TUTORIALS

    if name not in TUTORIALS:
        print(f"no tutorial named {name!r}; there are: {', '.join(TUTORIALS)}", file=sys.stderr)
        return 2
    import rclpy

    import tb4.navigator  # noqa: F401 - imported ahead, while the simulator boots

    module = importlib.import_module(f"tb4.tutorials.{name}")
    if "--ros-args" not in args:  # a tutorial given ROS arguments initialises rclpy with them itself
        # the tutorial's DDS participant, made now, finds the simulator's while it boots; the tutorial's
        # open_navigator then uses this context (it calls rclpy.init() only when rclpy is not ok)
        rclpy.init()
    try:
        opened = wait_at_start_gate()
    except RuntimeError as exc:
        print(f"{name}: {exc}", file=sys.stderr)
        return 2
    if not opened:
        print(f"{name}: tb4 run did not start the simulator; the tutorial does not run", file=sys.stderr)
        return 1
    sys.argv = [f"tb4.tutorials.{name}", *args]
    return int(module.main(args) or 0)


if __name__ == "__main__":
    if sys.argv[1:2] in (["--script"], ["--module"]):
        # a user's mission may register atexit handlers or leave buffered files: Python's own exit runs them
        sys.exit(main(sys.argv[1:]))
    # `tb4 run` waits for this process's exit before it stops the simulator: no interpreter finalization
    # (exit_now; the runner removes the shared-memory files it leaves)
    exit_now(main(sys.argv[1:]))
