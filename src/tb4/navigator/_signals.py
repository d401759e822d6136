"""SIGINT and SIGTERM end a navigator script, its running goals canceled first.

rclpy.init installs its own SIGINT and SIGTERM handlers: they shut every ROS context down, then hand the signal to
the handler that was there before. For SIGINT that is Python's, which raises KeyboardInterrupt; for SIGTERM there
is none (Python's default is to die), so the script carried on with a dead context: a navigator waiting for a
result waited forever, and the robot drove on.

`watch_signals` (called by every navigator built in the main thread) slips a Python handler in under rclpy's, for
each of the two signals still at Python's default: rclpy's handlers are taken out, ours set, and rclpy's put back,
so rclpy keeps doing what it did and then calls ours. Ours sends a cancel for every running goal of every live
navigator (the node and its DDS writers outlive the context's shutdown), waits up to CANCEL_WAIT wall seconds for
the answers (taking them itself once the context is shut down: an answer proves the server has the cancel), and then
raises, in the main thread, what a Python user expects:

- SIGINT: KeyboardInterrupt, as Python's own handler does: when nothing catches it, the process ends killed by
  SIGINT (a shell reports 130), as Python means it to (see _end_interrupted_process);
- SIGTERM: SystemExit(143), the status a process killed by SIGTERM reports (128 + 15), with `finally` blocks and
  atexit handlers run; `except Exception` does not catch it.

A handler the user installed, or rclpy.init(signal_handler_options=NO), is left alone; so is a navigator built in
another thread (Python sets handlers in the main thread only). Its waits still end: each raises rclpy's
ExternalShutdownException once it finds the context shut down (_task_client.TaskClient.check_context).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading
import time
import weakref
from types import FrameType
from typing import Any

from rclpy.signals import get_current_signal_handlers_options, install_signal_handlers, uninstall_signal_handlers

from tb4.navigator._task_client import CANCEL_WAIT
from tb4.processes import exit_now, flush_output
from tb4.ros.background import end_without_waiting_for_spinners

__all__ = ["watch_signals", "SIGTERM_EXIT_STATUS"]

SIGTERM_EXIT_STATUS = 128 + signal.SIGTERM  # 143: what a shell reports for a process SIGTERM ended

# which rclpy.signals.SignalHandlerOptions (by name: rclpy's type stubs misspell two) cover each signal
_RCLPY_HANDLES = {signal.SIGINT: ("ALL", "SIGINT"), signal.SIGTERM: ("ALL", "SIGTERM")}
_PYTHON_DEFAULTS = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}

_navigators: weakref.WeakSet[Any] = weakref.WeakSet()
_handling = False  # a second signal while the first one's cancels go out just raises
_terminated = False  # SIGTERM came: the process ends with SIGTERM_EXIT_STATUS once its atexit handlers ran
_interrupted = False  # SIGINT came and its KeyboardInterrupt was raised


def _end_signalled_process() -> None:
    """Registered first, so run last of the atexit handlers: after SIGTERM, or a SIGINT whose KeyboardInterrupt
    nobody caught (`_end_interrupted_process`), end the process here, before the interpreter's finalization collects
    rclpy objects whose context is gone (which can crash it: a segmentation fault instead of 143). `finally` blocks
    and the other atexit handlers have run by now."""
    if _terminated:
        exit_now(SIGTERM_EXIT_STATUS)
    if _interrupted and isinstance(getattr(sys, "last_value", None), KeyboardInterrupt):
        _end_interrupted_process()


def _end_interrupted_process() -> None:
    """End the process killed by SIGINT, which CPython does itself for a KeyboardInterrupt the main module left
    uncaught, but only after finalization and only if no thread ran a string eval or exec since: each one (a
    dataclass or namedtuple being made, a lazy import of a module that makes one) clears CPython's flag for it, and
    the script then exits with status 1, as for any error. The navigator's spin threads run callbacks while the
    atexit handlers wait for them, so the status was a matter of timing. Ending here also spares the finalization,
    as after SIGTERM. `sys.last_value` is the exception the interpreter printed as it left the main module."""
    flush_output()  # the signal below ends the process without Python's own flush
    with contextlib.suppress(OSError, ValueError):
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        os.kill(os.getpid(), signal.SIGINT)
    exit_now(128 + signal.SIGINT)  # the signal did not end the process: the status a shell would report


atexit.register(_end_signalled_process)


def watch_signals(navigator: Any) -> None:
    """Cancel `navigator`'s running goals on SIGINT/SIGTERM, and install the handlers if they are not (see above).

    Args:
        navigator: a BasicNavigator; held weakly, so a destroyed navigator is forgotten.
    """
    _navigators.add(navigator)
    if threading.current_thread() is not threading.main_thread():
        return
    options = get_current_signal_handlers_options()
    ours = [
        signum
        for signum, default in _PYTHON_DEFAULTS.items()
        if options.name in _RCLPY_HANDLES[signum] and signal.getsignal(signum) is default
    ]
    if not ours:
        return
    uninstall_signal_handlers()  # back to the Python handlers, which rclpy then calls after its own
    try:
        for signum in ours:
            signal.signal(signum, _on_signal)
    finally:
        install_signal_handlers(options)


def _on_signal(signum: int, _frame: FrameType | None) -> None:
    global _handling
    if not _handling:
        _handling = True
        try:
            _cancel_running_goals(signal.Signals(signum).name)
        finally:
            _handling = False
    if signum == signal.SIGINT:
        global _interrupted
        _interrupted = True
        raise KeyboardInterrupt
    global _terminated
    _terminated = True
    end_without_waiting_for_spinners()  # _end_signalled_process ends the process: no finalization to guard
    raise SystemExit(SIGTERM_EXIT_STATUS)


def _cancel_running_goals(signame: str) -> None:
    """Send every live navigator's cancels from a helper thread, joined for a bounded time: this runs in the main
    thread wherever the signal found it, possibly holding a lock the cancel needs."""
    navigators = [nav for nav in list(_navigators) if not getattr(nav, "_destroyed", True)]
    if not navigators:
        return
    helper = threading.Thread(target=_cancel, args=(navigators, signame), name="navigator-cancel", daemon=True)
    helper.start()
    helper.join(CANCEL_WAIT + 0.2)


def _cancel(navigators: list[Any], signame: str) -> None:
    deadline = time.monotonic() + CANCEL_WAIT
    sent: list[tuple[Any, str, Any]] = []
    for nav in navigators:
        try:
            sent.extend((nav, name, future) for name, future in nav._tasks.send_cancels())
        except Exception:  # noqa: BLE001 - best effort: a navigator being destroyed
            continue
    for nav, name, _future in sent:  # said at once: the main thread may end the process before any answer comes
        _say(f"[{nav.get_name()}] {signame}: cancel of the running '{name}' goal sent")
    for nav, name, future in sent:
        response = nav._tasks.wait_for_cancel_answer(future, deadline)
        if response is None:
            continue
        if response.goals_canceling:
            _say(f"[{nav.get_name()}] {signame}: the '{name}' server accepted the cancel")
        else:
            _say(f"[{nav.get_name()}] {signame}: the '{name}' server answered the cancel: nothing left to cancel")


def _say(line: str) -> None:
    # stderr rather than the node's logger: rclpy's logging may already be finalized when the signal comes
    with contextlib.suppress(Exception):  # a closed stderr must not stop the exit
        print(line, file=sys.stderr, flush=True)
