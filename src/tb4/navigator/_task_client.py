"""Action clients with bounded waits, and the one "current task" that isTaskComplete/getResult/... report on.

A goal's result completes a future in the executor thread; a done-callback sets an Event, so isTaskComplete()
answers as soon as the result is in (no fixed poll period). Each goal gets a generation number: feedback or a
result from an older goal (preempted, or sent before a rejected one) can never overwrite the current task.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient
from rclpy.node import Node

from tb4.navigator._spinner import _BACKSTOP, wait_for_future, wait_until
from tb4.navigator.results import TaskResult, status_name, task_result_of
from tb4.navigator.timeouts import NavigatorTimeout, NavigatorTimeouts, missing_server

__all__ = ["TaskClient", "REJECTED_CODE"]

REJECTED_CODE = 999  # Nav2's UNKNOWN for docking; used for every "goal rejected" error here
_EXECUTOR_HINT = (
    "; if you call the navigator from a callback of the executor that spins it, use a MultiThreadedExecutor "
    "or call it from another thread"
)


class TaskClient:
    """Owns the navigator's action clients and tracks the current task."""

    def __init__(
        self, node: Node, timeouts: Callable[[], NavigatorTimeouts], before_send: Callable[[], None] | None = None
    ) -> None:
        self._node = node
        self._before_send = before_send or (lambda: None)
        self._timeouts = timeouts
        self._clients: dict[str, ActionClient] = {}
        self._lock = threading.Lock()
        self._generation = 0
        self._done = threading.Event()
        self._done.set()
        self.goal_handle: Any = None
        self.result_future: Any = None
        self.feedback: Any = None
        self.status: int | None = None
        self.result: Any = None
        self.task_name = ""
        self.error: tuple[int, str] = (0, "")
        self.finished_at = -math.inf  # monotonic time the last result (task or one-shot call) arrived

    # --- clients ---------------------------------------------------------------------------------------------
    def add(self, action_type: Any, name: str) -> ActionClient:
        """Create the client now, so discovery runs in the background before the first goal."""
        if name not in self._clients:
            self._clients[name] = ActionClient(self._node, action_type, name)
        return self._clients[name]

    def client(self, name: str) -> ActionClient:
        return self._clients[name]

    def wait_for_server(self, name: str) -> ActionClient:
        client = self._clients[name]
        limit = self._timeouts().server
        if not wait_until(client.server_is_ready, limit):
            message = missing_server("action server", name, self._node.get_namespace(), limit)
            self._node.get_logger().error(message)
            raise NavigatorTimeout(message)
        return client

    def _send(self, name: str, goal: Any, feedback_callback: Callable[[Any], None] | None) -> Any:
        client = self.wait_for_server(name)
        self._before_send()
        future = client.send_goal_async(goal, feedback_callback=feedback_callback)
        limit = self._timeouts().response
        try:
            return wait_for_future(future, limit, f"the '{name}' server to accept or reject the goal")
        except NavigatorTimeout as exc:
            raise NavigatorTimeout(f"{exc}{_EXECUTOR_HINT}") from None

    def destroy(self) -> None:
        for client in self._clients.values():
            client.destroy()
        self._clients.clear()

    # --- the current task --------------------------------------------------------------------------------------
    def start(self, name: str, goal: Any) -> bool:
        """Send `goal` as the new current task. False (and an error) if the server rejected it."""
        with self._lock:
            self._generation += 1
            generation = self._generation
            self.goal_handle = None
            self.result_future = None
            self.feedback = None
            self.status = None
            self.result = None
            self.task_name = name
            self.error = (0, "")
            self._done.set()

        def on_feedback(msg: Any) -> None:
            with self._lock:
                if generation == self._generation:
                    self.feedback = msg.feedback

        try:
            handle = self._send(name, goal, on_feedback)
        except NavigatorTimeout as exc:
            self.error = (0, str(exc))
            raise
        with self._lock:
            if generation != self._generation:  # another thread started a task meanwhile: it is the current one
                return bool(handle.accepted)
            if not handle.accepted:
                self.error = (REJECTED_CODE, f"the '{name}' goal was rejected by the server")
                return False
            self.goal_handle = handle
            self._done.clear()
            result_future = self.result_future = handle.get_result_async()
        result_future.add_done_callback(lambda future: self._on_result(generation, future))
        return True

    def _on_result(self, generation: int, future: Any) -> None:
        with self._lock:
            if generation != self._generation or self._done.is_set():
                return
            response = future.result() if future.exception() is None else None
            if response is None:
                self.status = GoalStatus.STATUS_UNKNOWN
                self.error = (0, f"no result for the '{self.task_name}' goal: {future.exception()!r}")
            else:
                self.status = int(response.status)
                self.result = response.result
                if self.status != GoalStatus.STATUS_SUCCEEDED:
                    self.error = _error_of(response.result, self.status)
            self.finished_at = time.monotonic()
            self._done.set()

    def is_complete(self, wait: float) -> bool:
        """True when no task runs or the current one has finished; waits up to `wait` s for that to happen."""
        with self._lock:
            future, generation = self.result_future, self._generation
        if future is None:
            return True
        deadline = time.monotonic() + wait
        while not self._done.is_set():
            if future.done():  # its done-callback may sit in a stopped executor: handle the result here
                self._on_result(generation, future)
                break
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            self._done.wait(min(_BACKSTOP, remaining))
        return True

    def wait(self, timeout: float) -> bool:
        return self.is_complete(timeout)

    def task_result(self) -> TaskResult:
        return task_result_of(self.status)

    def status_text(self) -> str:
        code, msg = self.error
        text = f"status {status_name(self.status)}"
        if code or msg:
            text += f", error {code}: {msg}" if msg else f", error {code}"
        return text

    def cancel(self) -> bool:
        """Ask the server to cancel the current task; True if it accepted. The result arrives as CANCELED."""
        handle = self.goal_handle
        if handle is None or self._done.is_set():
            return False
        self._before_send()
        future = handle.cancel_goal_async()
        response = wait_for_future(future, self._timeouts().response, f"the '{self.task_name}' server to cancel")
        return bool(response is not None and len(response.goals_canceling) > 0)

    # --- one-shot calls (planning, smoothing, docking helpers) -------------------------------------------------
    def call(self, name: str, goal: Any) -> tuple[int | None, Any]:
        """Send a goal and wait for its result, without touching the current task. (None, None) if rejected."""
        handle = self._send(name, goal, None)
        if not handle.accepted:
            return None, None
        limit = self._timeouts().result
        response = wait_for_future(handle.get_result_async(), limit, f"the result of the '{name}' goal")
        self.finished_at = time.monotonic()
        return int(response.status), response.result


def _error_of(result: Any, status: int) -> tuple[int, str]:
    code = int(getattr(result, "error_code", 0) or 0)
    msg = str(getattr(result, "error_msg", "") or "")
    if not msg and status == GoalStatus.STATUS_CANCELED:
        msg = "the task was canceled"
    return code, msg
