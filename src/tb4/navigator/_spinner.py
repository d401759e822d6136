"""The navigator's own executor thread, so waits (tb4.core.waits) are events on futures instead of spinning.

Upstream calls rclpy.spin_until_future_complete on the navigator node, which breaks when the node also belongs to
the user's executor. Here a daemon thread spins the node, so futures complete in the background and every wait
is a threading.Event with a deadline. If the user adds the node to their own executor, rclpy moves it there
(a node belongs to one executor); our thread notices when the user lets go of it and takes it back.
"""

from __future__ import annotations

import atexit
import contextlib
import threading
import time
import weakref
from collections.abc import Iterator

from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

__all__ = ["BackgroundSpinner"]


class BackgroundSpinner:
    """Spins one node in a daemon thread until stopped or the context shuts down."""

    def __init__(self, node: Node) -> None:
        self._node = node
        self._executor = SingleThreadedExecutor(context=node.context)
        self._stop = threading.Event()
        # Held around each spin_once: creating an entity under it keeps this thread out of the node while rclpy
        # has registered the entity but not finished building it (an ActionClient's _lock comes last).
        self._spin_lock = threading.RLock()
        self._pausers = 0  # threads waiting in paused(): the loop yields the lock to them
        self._pausers_lock = threading.Lock()
        self._thread = threading.Thread(target=self._run, name=f"navigator-spin-{node.get_name()}", daemon=True)
        self._started = False

    def start(self) -> None:
        """Start spinning: call it once the node is completely built (BasicNavigator does, after every __init__)."""
        with self._spin_lock:
            if self._started or self._stop.is_set():
                return
            self._started = True
            self._executor.add_node(self._node)
            self._thread.start()
        # A script that ends without rclpy.shutdown() must not abort in C++ while this thread still waits.
        atexit.register(_stop_at_exit, weakref.ref(self))

    @property
    def started(self) -> bool:
        return self._started

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        """Keep the executor thread out of the node while a client/subscription is being created."""
        with self._pausers_lock:
            self._pausers += 1
        try:
            self._executor.wake()
            with self._spin_lock:
                yield
        finally:
            with self._pausers_lock:
                self._pausers -= 1

    @property
    def spun_elsewhere(self) -> bool:
        """True while the node belongs to another (the user's) executor."""
        current = self._node.executor
        return current is not None and current is not self._executor and self._node in current.get_nodes()

    def ensure_spun(self) -> None:
        """Take the node back now if no executor holds it (called before sending requests)."""
        if not self._started:
            self.start()
        elif not self._stop.is_set():
            self._adopt_if_orphaned()

    def _adopt_if_orphaned(self) -> None:
        current = self._node.executor
        if current is self._executor and self._node in self._executor.get_nodes():
            return
        if current is None or self._node not in current.get_nodes():
            self._executor.add_node(self._node)

    def _run(self) -> None:
        context = self._node.context
        while not self._stop.is_set() and context.ok():
            if self._pausers > 0:
                time.sleep(0.001)
                continue
            try:
                with self._spin_lock:
                    self._adopt_if_orphaned()
                    self._executor.spin_once(timeout_sec=0.05)
            except ExternalShutdownException:
                return
            except Exception as exc:  # noqa: BLE001 - keep serving; a dying context ends the loop above
                if self._stop.is_set() or not context.ok():
                    return
                self._node.get_logger().error(f"navigator executor: {type(exc).__name__}: {exc}")
                time.sleep(0.05)

    def stop(self) -> None:
        self._stop.set()
        self._executor.wake()
        if self._started and threading.current_thread() is not self._thread:
            self._thread.join(timeout=2.0)
        with contextlib.suppress(Exception):  # the node may already be destroyed
            self._executor.remove_node(self._node)
        self._executor.shutdown(timeout_sec=0.5)


def _stop_at_exit(ref: weakref.ReferenceType[BackgroundSpinner]) -> None:
    spinner = ref()
    if spinner is not None and not spinner._stop.is_set():
        spinner._stop.set()
        spinner._thread.join(timeout=1.0)
