"""Action clients with bounded waits, and the running tasks that isTaskComplete/getFeedback/getResult report on.

Two task slots, as in upstream Kilted: `main` holds the one current task (navigation, following, behaviours,
docking); `route` holds a compute_and_track_route goal, which runs beside a follow_path or waypoint task, keeps
every feedback message in order (getFeedback(task=COMPUTE_AND_TRACK_ROUTE) pops them one by one) and is canceled
together with the main task by cancelTask().

A goal's result completes a future in the executor thread; a done-callback sets an Event, so isTaskComplete()
answers as soon as the result is in (no fixed poll period). Each goal gets a generation number: feedback or a
result from an older goal (preempted, or sent before a rejected one) can never overwrite the current task.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus

from tb4.core.waits import POLL_BACKSTOP, wait_for_future
from tb4.navigator._clients import ClientOwner, ClientSetup
from tb4.navigator.results import TaskResult, status_name, task_result_of
from tb4.navigator.timeouts import NavigatorTimeout
from tb4.ros.action_client import ActionClient
from tb4.wire import result_code

__all__ = ["TaskClient", "TaskSlot", "REJECTED_CODE", "ROUTE_FEEDBACK_LIMIT"]

REJECTED_CODE = 999  # Nav2's UNKNOWN for docking; used where an action defines no UNKNOWN of its own
ROUTE_FEEDBACK_LIMIT = 10_000  # route feedback kept for getFeedback; the oldest goes first past this
_EXECUTOR_HINT = (
    "; if you call the navigator from a callback of the executor that spins it, use a MultiThreadedExecutor "
    "or call it from another thread"
)


def rejected_code(action_type: Any) -> int:
    """The action's own UNKNOWN error code (NavigateToPose 9000, Spin 700, ...): what Nav2 reports for it."""
    try:
        return result_code(action_type, "UNKNOWN")  # on a Jazzy build, Kilted's number where Jazzy names none
    except KeyError:
        return REJECTED_CODE


class TaskSlot:
    """One running goal: its handle, result future, latest feedback (or every route feedback), status and result."""

    def __init__(self, lock: threading.Lock, queue_feedback: bool) -> None:
        self._lock = lock
        self.queue_feedback = queue_feedback
        self.generation = 0
        self.done = threading.Event()
        self.done.set()
        self.goal_handle: Any = None
        self.result_future: Any = None
        self.feedback: Any = None
        self.feedback_queue: deque[Any] = deque(maxlen=ROUTE_FEEDBACK_LIMIT)
        self.status: int | None = None
        self.result: Any = None
        self.task_name = ""

    def reset(self, name: str) -> int:
        """Forget the previous goal (caller holds the lock); returns the new generation."""
        self.generation += 1
        self.goal_handle = None
        self.result_future = None
        self.feedback = None
        self.feedback_queue.clear()
        self.status = None
        self.result = None
        self.task_name = name
        self.done.set()
        return self.generation

    def on_feedback(self, generation: int, msg: Any) -> None:
        with self._lock:
            if generation == self.generation:
                self.feedback = msg.feedback
                if self.queue_feedback:
                    self.feedback_queue.append(msg.feedback)

    def pop_feedback(self) -> Any:
        with self._lock:
            return self.feedback_queue.popleft() if self.feedback_queue else None

    def running(self) -> bool:
        return self.result_future is not None and not self.done.is_set()


class TaskClient(ClientOwner[ActionClient]):
    """Owns the navigator's action clients and tracks the running tasks (see the module docstring)."""

    def __init__(self, setup: ClientSetup) -> None:
        super().__init__(setup)
        self._types: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.main = TaskSlot(self._lock, queue_feedback=False)
        self.route = TaskSlot(self._lock, queue_feedback=True)
        self.reported = self.main  # the slot getResult reports on: the last one isTaskComplete saw finish
        self.error: tuple[int, str] = (0, "")
        self.finished_at = -math.inf  # monotonic time the last result (task or one-shot call) arrived
        # called (under the lock, from whichever thread handles it) with each slot whose task has just finished
        self.on_finished: Callable[[TaskSlot], None] | None = None

    # --- upstream's attributes of the main task -----------------------------------------------------------------
    @property
    def goal_handle(self) -> Any:
        return self.main.goal_handle

    @property
    def result_future(self) -> Any:
        return self.main.result_future

    @property
    def feedback(self) -> Any:
        return self.main.feedback

    @property
    def status(self) -> int | None:
        return self.reported.status

    @property
    def result(self) -> Any:
        return self.reported.result

    @property
    def task_name(self) -> str:
        return self.reported.task_name

    # --- clients ---------------------------------------------------------------------------------------------
    def add(self, action_type: Any, name: str) -> ActionClient:
        """Create the client now (under ClientSetup.creating), so discovery runs in the background before the
        first goal."""
        client = self._client(name, lambda: ActionClient(self._node, action_type, name))
        self._types[name] = action_type
        return client

    def client(self, name: str) -> ActionClient:
        return self._clients[name]

    def wait_for_server(self, name: str) -> ActionClient:
        client = self._clients[name]
        self._wait_for_server(client.server_is_ready, "action server", name, self._timeouts().server)
        return client

    def _send(self, name: str, goal: Any, feedback_callback: Callable[[Any], None] | None) -> Any:
        client = self.wait_for_server(name)
        self._before_send()
        future = client.send_goal_async(goal, feedback_callback=feedback_callback)
        limit = self._timeouts().response
        try:
            return wait_for_future(future, limit, f"the '{name}' server to accept or reject the goal", NavigatorTimeout)
        except NavigatorTimeout as exc:
            raise NavigatorTimeout(f"{exc}{_EXECUTOR_HINT}") from None

    def destroy(self) -> None:
        for client in self._clients.values():
            client.destroy()
        self._clients.clear()

    # --- running tasks -------------------------------------------------------------------------------------------
    def start(self, name: str, goal: Any, slot: TaskSlot | None = None) -> bool:
        """Send `goal` as the new task of `slot` (main by default). False (and an error) if it was rejected."""
        slot = slot or self.main
        with self._lock:
            generation = slot.reset(name)
            self.reported = slot
            self.error = (0, "")

        def on_feedback(msg: Any) -> None:
            slot.on_feedback(generation, msg)

        try:
            handle = self._send(name, goal, on_feedback)
        except NavigatorTimeout as exc:
            self.error = (0, str(exc))
            raise
        with self._lock:
            if generation != slot.generation:  # another thread started a task meanwhile: it is the current one
                return bool(handle.accepted)
            if not handle.accepted:
                self.error = (rejected_code(self._types[name]), f"the '{name}' goal was rejected")
                return False
            slot.goal_handle = handle
            slot.done.clear()
            result_future = slot.result_future = handle.get_result_async()
        result_future.add_done_callback(lambda future: self._on_result(slot, generation, future))
        return True

    def _on_result(self, slot: TaskSlot, generation: int, future: Any) -> None:
        with self._lock:
            if generation != slot.generation or slot.done.is_set():
                return
            response = future.result() if future.exception() is None else None
            if response is None:
                slot.status = GoalStatus.STATUS_UNKNOWN
                self.error = (0, f"no result for the '{slot.task_name}' goal: {future.exception()!r}")
            else:
                slot.status = int(response.status)
                slot.result = response.result
                if slot.status != GoalStatus.STATUS_SUCCEEDED:
                    self.error = _error_of(response.result, slot.status)
            self.finished_at = time.monotonic()
            slot.done.set()
            if self.on_finished is not None:
                self.on_finished(slot)

    def is_complete(self, wait: float, slot: TaskSlot | None = None) -> bool:
        """True when `slot` runs nothing or its task has finished; waits up to `wait` s for that to happen."""
        slot = slot or self.main
        with self._lock:
            future, generation = slot.result_future, slot.generation
        if future is None:
            return True
        deadline = time.monotonic() + wait
        while not slot.done.is_set():
            if future.done():  # its done-callback may sit in a stopped executor: handle the result here
                self._on_result(slot, generation, future)
                break
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            slot.done.wait(min(POLL_BACKSTOP, remaining))
        with self._lock:
            if generation == slot.generation:
                self.reported = slot
        return True

    def task_result(self) -> TaskResult:
        return task_result_of(self.reported.status)

    def status_text(self) -> str:
        code, msg = self.error
        text = f"status {status_name(self.reported.status)}"
        if code or msg:
            text += f", error {code}: {msg}" if msg else f", error {code}"
        return text

    def cancel(self) -> bool:
        """Ask the servers to cancel the running tasks (main and route); True if one accepted. Results then read
        CANCELED."""
        accepted = False
        for slot in (self.main, self.route):
            handle = slot.goal_handle
            if handle is None or not slot.running():
                continue
            self._before_send()
            future = handle.cancel_goal_async()
            what = f"the '{slot.task_name}' server to cancel"
            response = wait_for_future(future, self._timeouts().response, what, NavigatorTimeout)
            accepted |= bool(response is not None and len(response.goals_canceling) > 0)
        return accepted

    # --- one-shot calls (planning, smoothing, routes, docking helpers) --------------------------------------------
    def call(self, name: str, goal: Any) -> tuple[int | None, Any]:
        """Send a goal and wait for its result, without touching the running tasks. (None, None) if rejected."""
        handle = self._send(name, goal, None)
        if not handle.accepted:
            return None, None
        limit = self._timeouts().result
        response = wait_for_future(
            handle.get_result_async(), limit, f"the result of the '{name}' goal", NavigatorTimeout
        )
        self.finished_at = time.monotonic()
        return int(response.status), response.result


def _error_of(result: Any, status: int) -> tuple[int, str]:
    code = int(getattr(result, "error_code", 0) or 0)
    msg = str(getattr(result, "error_msg", "") or "")
    if not msg and status == GoalStatus.STATUS_CANCELED:
        msg = "the task was canceled"
    return code, msg
