"""The one way tb4 spins ROS nodes on a background thread.

`BackgroundSpinner` spins an executor in a daemon thread until stopped or its context shuts down; one turn is one
`spin_once`, and a user of it that must do more per turn (the viewer drains at a bounded pace) overrides `turn()`.
Options the navigator needs and the others don't: `adopt` takes the node back when a user's executor lets go of it
(rclpy moves a node to the last executor it was added to), and `paused()` keeps the thread out of the node while
an entity is being built. `BackgroundNode` is a node in a context of its own, spun that way: for watchers that live
beside other ROS code in one process (the run monitor, the recorder, the tutorials' second nodes).
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import importlib.metadata
import os
import threading
import time
import weakref
from collections.abc import Callable, Iterator, Sequence

import rclpy
from rclpy.context import Context
from rclpy.executors import Executor, ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from tb4.processes import abandoned_ports_watched

__all__ = [
    "BackgroundSpinner",
    "BackgroundNode",
    "EXECUTOR_ENV",
    "destroy_node_and_actions",
    "end_without_waiting_for_spinners",
    "events_executor_complete",
    "spinner_executor",
]

ERROR_PAUSE = 0.05  # s slept after a failed turn, so a persistent error does not spin the CPU

_ending_by_exit = False  # set by end_without_waiting_for_spinners


def end_without_waiting_for_spinners() -> None:
    """Say that this process ends with os._exit once its atexit handlers have run (tb4.navigator._signals after
    SIGTERM). Spin threads are joined only so that none is still in rclpy's C++ when the interpreter finalizes; no
    finalization follows os._exit, so from now on a stop (BackgroundSpinner.stop, the exit handlers) tells the
    thread to end and does not wait for it. A spin thread blocked on a context that was shutting down held each of
    those joins for its whole timeout, and a script's exit after SIGTERM for their sum.
    """
    global _ending_by_exit
    _ending_by_exit = True


#: Which executor spins a node whose user may attach anything to it (the navigator): auto, events or single.
EXECUTOR_ENV = "TB4_NAVIGATOR_EXECUTOR"
EXECUTOR_CHOICES = ("auto", "events", "single")

# The first rclpy releases whose EventsExecutor awaits an async subscription or service callback: Jazzy's backport
# before 7.1.11 creates the coroutine and never runs it (a user's `async def` callback on the navigator's node
# would silently do nothing); Kilted's runs it.
_EVENTS_COMPLETE_SINCE = {7: (7, 1, 11), 9: (9, 0, 0)}


@functools.cache
def events_executor_complete() -> bool:
    """Whether this rclpy's EventsExecutor runs everything a user may add to a node (subscriptions, services, clients,
    action clients, async callbacks), so it may spin a node the user also builds on. Cached: reading a package's
    version scans the site-packages folder, milliseconds that each navigator of a sweep's trials would pay again.

    Returns:
        True on rclpy releases known to (Kilted's 9.x and later, Jazzy's from 7.1.11); False before them, or when
        rclpy's version cannot be read (a source build), or it has no EventsExecutor.
    """
    try:
        from rclpy.experimental import EventsExecutor  # noqa: F401
    except ImportError:
        return False
    try:
        parts = tuple(int(p) for p in importlib.metadata.version("rclpy").split(".")[:3])
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return False
    if len(parts) < 3:
        return False
    if parts[0] > max(_EVENTS_COMPLETE_SINCE):
        return True
    since = _EVENTS_COMPLETE_SINCE.get(parts[0])
    return since is not None and parts >= since


def spinner_executor(context: Context) -> Executor:
    """The executor for a node a user builds on (the navigator's), chosen by the TB4_NAVIGATOR_EXECUTOR environment
    variable: `auto` (default) is rclpy's EventsExecutor where it is complete (`events_executor_complete`), else a
    SingleThreadedExecutor; `events` and `single` choose one.

    The EventsExecutor dispatches each message from C++: the SingleThreadedExecutor rebuilds its wait set in Python at
    every wake-up, and a navigator wakes for every /clock, amcl_pose and feedback message. rclpy still calls it
    experimental, hence the way back.

    Args:
        context: the context the executor serves.

    Returns:
        The executor, not yet spinning.

    Raises:
        ValueError: the environment variable names no known executor.
    """
    choice = os.environ.get(EXECUTOR_ENV, "").strip().lower() or "auto"
    if choice not in EXECUTOR_CHOICES:
        raise ValueError(f"{EXECUTOR_ENV}={choice!r}: expected one of {', '.join(EXECUTOR_CHOICES)}")
    if choice == "events" or (choice == "auto" and events_executor_complete()):
        from rclpy.experimental import EventsExecutor

        return EventsExecutor(context=context)
    return SingleThreadedExecutor(context=context)


class BackgroundSpinner:
    """Spins `nodes` (more can be added later) with `executor` in a daemon thread named `name`.

    Without `executor`, a SingleThreadedExecutor in `context` (default: the first node's, else rclpy's).
    `on_error(exc)` hears about an exception from a turn (the loop goes on); without it errors are dropped.
    `adopt`: before each turn, add the first node back if no executor holds it any more.
    `stop_at_exit`: stop the thread when the interpreter exits (a script that never calls rclpy.shutdown()
    must not abort in C++ while this thread still waits).
    """

    def __init__(
        self,
        nodes: Node | Sequence[Node] = (),
        *,
        name: str,
        executor: Executor | None = None,
        context: Context | None = None,
        spin_timeout: float = 0.1,
        on_error: Callable[[Exception], None] | None = None,
        adopt: bool = False,
        stop_at_exit: bool = False,
    ) -> None:
        self.nodes: list[Node] = [nodes] if isinstance(nodes, Node) else list(nodes)
        if executor is None:
            context = context or (self.nodes[0].context if self.nodes else None)
            executor = SingleThreadedExecutor(context=context)
        self.executor = executor
        self.context = self.executor.context
        self.spin_timeout = spin_timeout
        self.on_error = on_error
        self.adopt = adopt
        self.stop_at_exit = stop_at_exit
        self._stop = threading.Event()
        # Held around each turn: creating an entity under it (paused()) keeps this thread out of the node while
        # rclpy has registered the entity but not finished building it (an ActionClient's _lock comes last).
        self._turn_lock = threading.RLock()
        self._pausers = 0
        self._pausers_lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._started = False

    # --- control (any thread) -------------------------------------------------------------------------------
    def start(self) -> None:
        """Start spinning (once the nodes are completely built); a second call does nothing."""
        with self._turn_lock:
            if self._started or self._stop.is_set():
                return
            self._started = True
            for node in self.nodes:
                self.executor.add_node(node)
            self._thread.start()
        if self.stop_at_exit:
            atexit.register(_stop_at_exit, weakref.ref(self))

    @property
    def started(self) -> bool:
        return self._started

    @property
    def alive(self) -> bool:
        """Whether the spin thread still runs."""
        return self._thread.is_alive()

    @property
    def stopping(self) -> bool:
        return self._stop.is_set()

    def stop(self, timeout: float = 2.0) -> None:
        """End the thread (waiting at most `timeout` s for it, unless the process ends without finalization: see
        end_without_waiting_for_spinners) and shut the executor down."""
        self._stop.set()
        self.executor.wake()
        if self._started and threading.current_thread() is not self._thread and not _ending_by_exit:
            if _in_context_shutdown(self.context):
                atexit.register(_join_at_exit, self._thread, timeout)  # it must not outlive the interpreter
            else:
                self._thread.join(timeout=timeout)
        for node in self.nodes:
            with contextlib.suppress(Exception):  # the node may already be destroyed
                self.executor.remove_node(node)
        self.executor.shutdown(timeout_sec=0.5)

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        """Keep the spin thread out of the nodes while a client/subscription is being created."""
        with self._pausers_lock:
            self._pausers += 1
        try:
            self.executor.wake()
            with self._turn_lock:
                yield
        finally:
            with self._pausers_lock:
                self._pausers -= 1

    @property
    def spun_elsewhere(self) -> bool:
        """True while the (first) node belongs to another executor (the user's)."""
        if not self.nodes:
            return False
        current = self.nodes[0].executor
        return current is not None and current is not self.executor and self.nodes[0] in current.get_nodes()

    def ensure_spun(self) -> None:
        """Start, or take the node back now if no executor holds it (called before sending requests)."""
        if not self._started:
            self.start()
        elif not self._stop.is_set() and self.adopt and self._orphaned() and not _in_context_shutdown(self.context):
            # out of the spin thread's turn: an EventsExecutor's add_node must not race its own spin (and not inside
            # rclpy.shutdown(), where the spin thread may hold its turn while it waits for the context's lock)
            with self.paused():
                self._adopt_if_orphaned()

    # --- the thread -------------------------------------------------------------------------------------------
    def turn(self) -> None:
        """One turn of the loop: handle what is ready, waiting at most `spin_timeout`."""
        self.executor.spin_once(timeout_sec=self.spin_timeout)

    def finish(self) -> None:
        """Runs in the thread when the loop ends (override to clean up where the nodes were spun)."""

    def _orphaned(self) -> bool:
        """Whether the first node is in no executor's hands: not this one's, and not (any more) another's."""
        node = self.nodes[0]
        current = node.executor
        if current is self.executor and node in self.executor.get_nodes():
            return False
        return current is None or node not in current.get_nodes()

    def _adopt_if_orphaned(self) -> None:
        if self._orphaned():
            self.executor.add_node(self.nodes[0])

    def _run(self) -> None:
        try:
            while not self._stop.is_set() and self.context.ok():
                if self._pausers > 0:
                    time.sleep(0.001)
                    continue
                try:
                    with self._turn_lock:
                        if self.adopt and self.nodes:
                            self._adopt_if_orphaned()
                        self.turn()
                except ExternalShutdownException:
                    return
                except Exception as exc:  # noqa: BLE001 - keep serving; a dying context ends the loop above
                    if self._stop.is_set() or not self.context.ok():
                        return
                    if self.on_error is not None:
                        self.on_error(exc)
                    time.sleep(ERROR_PAUSE)
        finally:
            self.finish()


def _in_context_shutdown(context: Context) -> bool:
    """Whether this thread is inside rclpy's Context.shutdown(), which destroys the nodes (and so stops their
    spinners) while it holds the context's lock. The spin thread then waits for that lock in context.ok() and
    cannot end before shutdown() returns; joining it would only wait out the timeout (2 s at every script's
    rclpy.shutdown()). It ends right after, when ok() turns False, and is joined at exit (a spin thread still in
    rclpy's C++ when the interpreter ends aborts the process). rclpy keeps the lock in `Context._lock`, an RLock,
    which says whether this thread holds it; without it, join as before."""
    is_owned = getattr(getattr(context, "_lock", None), "_is_owned", None)
    return bool(is_owned()) if callable(is_owned) else False


def _stop_at_exit(ref: weakref.ReferenceType[BackgroundSpinner]) -> None:
    spinner = ref()
    if spinner is not None and not spinner._stop.is_set():
        spinner._stop.set()
        _join_at_exit(spinner._thread, 1.0)


def _join_at_exit(thread: threading.Thread, timeout: float) -> None:
    """Wait (at most `timeout` s) for a spin thread at exit, unless no finalization follows."""
    if not _ending_by_exit:
        thread.join(timeout=timeout)


def destroy_node_and_actions(node: Node) -> None:
    """node.destroy_node(), after destroying its action clients and servers. rclpy's destroy_node leaves those to the
    garbage collector, and until it runs they keep the node, and its DDS participant with its ports, alive. A
    process that makes and drops nodes (a test session) then piles up participants, and with LOCALHOST discovery
    a participant numbered past the first 32 of a domain on the machine is not discovered by another such one."""
    for waitable in list(node.waitables):
        destroy = getattr(waitable, "destroy", None)
        if destroy is not None:
            destroy()
    node.destroy_node()


class BackgroundNode:
    """A node in a context of its own. Create with a name; add subscriptions to `.node`, then call `start()`;
    `close()` ends it all.

    `events_executor`: spin with rclpy's EventsExecutor, which dispatches each message from C++ instead of
    rebuilding a wait set in Python per wake-up: several times less CPU per message, for a watcher that takes
    thousands of messages per wall second (the run monitor at --rate max). Plain subscriptions only."""

    def __init__(
        self, name: str, namespace: str = "", signal_handlers: bool = True, events_executor: bool = False
    ) -> None:
        self.context = rclpy.Context()
        options = rclpy.signals.SignalHandlerOptions.ALL if signal_handlers else rclpy.signals.SignalHandlerOptions.NO
        rclpy.init(context=self.context, signal_handler_options=options)
        with abandoned_ports_watched():  # the context's participant is made with its first node
            self.node: Node = rclpy.create_node(name, namespace=namespace or "/", context=self.context)
        executor: Executor | None = None
        if events_executor:
            from rclpy.experimental import EventsExecutor

            executor = EventsExecutor(context=self.context)
        self._spinner = BackgroundSpinner(self.node, name=name, executor=executor)

    def start(self) -> None:
        self._spinner.start()

    def paused(self) -> contextlib.AbstractContextManager[None]:
        """Keep the spin thread out of the node while an action client or server is built (rclpy registers one
        with the node before it is complete)."""
        return self._spinner.paused()

    def close(self) -> None:
        rclpy.try_shutdown(context=self.context)  # ends the spin loop first
        self._spinner.stop()
        destroy_node_and_actions(self.node)
