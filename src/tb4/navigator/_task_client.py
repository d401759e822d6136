"""Action clients with bounded waits, and the running tasks that isTaskComplete/getFeedback/getResult report on.

Two task slots, as in upstream Kilted: `main` holds the one current task (navigation, following, behaviours,
docking); `route` holds a compute_and_track_route goal, which runs beside a follow_path or waypoint task, keeps
every feedback message in order (getFeedback(task=COMPUTE_AND_TRACK_ROUTE) pops them one by one) and is canceled
together with the main task by cancelTask().

A goal's result completes a future in the executor thread; a done-callback sets an Event, so isTaskComplete()
answers as soon as the result is in (no fixed poll period). Each goal gets a generation number: feedback or a
result from an older goal (preempted, or sent before a rejected one) can never overwrite the current task.

A goal whose server went away (_liveness.ServerWatch, checked on every turn of every wait) ends ABORTED with a task
error saying so, its cancel sent in case the server was only stalled. A wait that finds the ROS context shut down
(rclpy's SIGINT/SIGTERM handler does that) sends the running goals' cancels and raises ExternalShutdownException,
as rclpy's own spin does: nothing can arrive any more.

A goal can be running before its client knows it: the server has accepted it and started driving while its goal
response still waits to be taken (a busy executor, a loaded machine), or was lost. Every goal is therefore sent with
an id of ours and stays a PendingGoal until its handle is in place: a cancel then goes out by that id (CancelGoal
names the goal without a handle), on a signal, on cancelTask(), and when the goal response does not come in time.
A server that had not accepted the goal yet cancels nothing; if the goal is accepted later, the goal response's
callback sends the cancel again through the handle (in the executor thread, while the context lives).
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from action_msgs.msg import GoalStatus
from rclpy.executors import ExternalShutdownException

from tb4.core.waits import POLL_BACKSTOP, wait_for_future
from tb4.navigator._clients import ClientOwner, ClientSetup
from tb4.navigator._liveness import ServerWatch
from tb4.navigator.results import TaskResult, status_name, task_result_of
from tb4.navigator.timeouts import NavigatorTimeout
from tb4.ros.action_client import ActionClient, GoalSend
from tb4.wire import result_code, set_supported

__all__ = ["TaskClient", "TaskSlot", "ServerLost", "REJECTED_CODE", "ROUTE_FEEDBACK_LIMIT"]

REJECTED_CODE = 999  # Nav2's UNKNOWN for docking; used where an action defines no UNKNOWN of its own
ROUTE_FEEDBACK_LIMIT = 10_000  # route feedback kept for getFeedback; the oldest goes first past this
SIGNAL_LOCK_WAIT = 0.05  # s send_cancels waits for a client's lock before sending without it (cancel_goal_id_async)
CANCEL_WAIT = 0.5  # wall s the cancels sent once the context is shut down wait for their answers, in all
_EXECUTOR_HINT = (
    "; if you call the navigator from a callback of the executor that spins it, use a MultiThreadedExecutor "
    "or call it from another thread"
)


class ServerLost(Exception):
    """A goal's action server went away while the navigator waited for it; the message says how (_liveness)."""


class PendingGoal:
    """A goal sent whose handle is not in place yet: its action, client and id, and whether a cancel was asked."""

    def __init__(self, name: str, client: ActionClient) -> None:
        self.name = name
        self.client = client
        self.goal_id = client.new_goal_id()
        self.cancel_requested = False
        self.cancel_future: Any = None
        self.send: GoalSend | None = None  # once sent: the goal may go again under new ids (tb4.ros.action_client)

    def cancel(self, lock_timeout: float = -1) -> Any:
        """Send a cancel by each id the goal was sent under (see the module docstring), and send it no more;
        returns the future the latest id's answer completes. Safe from any thread, the context shut down or not
        (`lock_timeout`: see cancel_goal_id_async)."""
        self.cancel_requested = True  # before sending: a goal response taken meanwhile sees it (on_response)
        goal_ids = [self.goal_id]
        if self.send is not None:
            self.send.stop_resending()
            goal_ids = list(self.send.goal_ids) or goal_ids
        for goal_id in goal_ids:
            self.cancel_future = self.client.cancel_goal_id_async(goal_id, lock_timeout)
        return self.cancel_future

    def on_response(self, future: Any) -> None:
        """The goal response's callback: a goal accepted after its cancel was asked for is canceled now, unless
        the cancel by id already found it (its answer says so)."""
        if not self.cancel_requested or future.exception() is not None:
            return
        handle = future.result()
        if handle is None or not handle.accepted:
            return
        answer = self.cancel_future
        if answer is not None and answer.done() and answer.exception() is None and answer.result().goals_canceling:
            return
        with contextlib.suppress(Exception):  # best effort: a client being destroyed
            handle.cancel_goal_async()


def rejected_code(action_type: Any) -> int:
    """The action's own UNKNOWN error code (NavigateToPose 9000, Spin 700, ...): what Nav2 reports for it."""
    try:
        return result_code(action_type, "UNKNOWN")  # on a Jazzy build, Kilted's number where Jazzy names none
    except KeyError:
        return REJECTED_CODE


class _ContextShutDown(Exception):
    """The ROS context was shut down during a wait whose caller deals with that itself (TaskClient._cancel_answer)."""


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
        self.watch: ServerWatch | None = None

    def reset(self, name: str) -> int:
        """Forget the previous goal (caller holds the lock); returns the new generation."""
        self.generation += 1
        if self.watch is not None:
            self.watch.close()
        self.watch = None
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
        self._parked: set[str] = set()  # clients created but not yet used: out of the executor's wait set (add)
        self._pending: set[PendingGoal] = set()  # goals sent whose handle is not in place yet (see the docstring)
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
        first goal, but leave it out of the executor's wait set until its first use (`_in_use`).

        rclpy's executor rebuilds its wait set from every entity of the node at each wake-up, in Python: with all
        eighteen of Nav2's and the TurtleBot 4's action clients in it, a wake-up (each /clock, amcl_pose or
        feedback message) cost the navigator's thread several times what the message itself does, and a script
        uses two or three of them. Created late instead, a client's first goal would race its own discovery (the
        server may not have matched the reply reader yet, and the reply is lost): parked, it is discovered as
        before and only its reads wait.
        """
        created = name not in self._clients
        client = self._client(name, lambda: ActionClient(self._node, action_type, name))
        if created:
            with self._creating():  # the executor thread stays out of the node meanwhile
                self._node.remove_waitable(client)
            self._parked.add(name)
        self._types[name] = action_type
        return client

    def _in_use(self, name: str) -> ActionClient:
        """The client called `name`, in the executor's wait set from now on (see `add`)."""
        client = self._clients[name]
        if name in self._parked:
            self._parked.discard(name)
            with self._creating():  # out of the spin thread's turn, as when it was created
                self._node.add_waitable(client)  # wakes the executor: its next wait takes the client's replies
        return client

    def client(self, name: str) -> ActionClient:
        return self._in_use(name)

    def wait_for_server(self, name: str) -> ActionClient:
        client = self._in_use(name)
        self._wait_for_server(
            client.server_is_ready, "action server", name, self._timeouts().server, client.graph_report
        )
        return client

    def _send(self, name: str, goal: Any, feedback_callback: Callable[[Any], None] | None) -> tuple[Any, PendingGoal]:
        """Send the goal and wait for its goal response; returns the goal handle and the PendingGoal, which stays
        in `_pending` until the caller has put the handle in place (then it calls `_sent`).

        Raises:
            NavigatorTimeout: no goal response within the limit (the goal's cancel is sent by its id: a goal
                accepted whose response was lost must not drive on unwatched).
        """
        client = self.wait_for_server(name)
        self._before_send()
        pending = PendingGoal(name, client)
        self._pending.add(pending)
        try:
            future = client.send_goal_async(goal, feedback_callback=feedback_callback, goal_uuid=pending.goal_id)
            pending.send = future
            future.add_done_callback(pending.on_response)
            limit = self._timeouts().response
            try:
                return self._wait(future, limit, f"the '{name}' server to accept or reject the goal"), pending
            except NavigatorTimeout as exc:
                with contextlib.suppress(Exception):  # best effort: the timeout is the error to report
                    pending.cancel()
                raise NavigatorTimeout(f"{exc} (its cancel was sent){_EXECUTOR_HINT}") from None
        except BaseException:
            self._sent(pending)
            raise

    def _sent(self, pending: PendingGoal) -> None:
        """The goal's handle is in place (or there is none to wait for): cancels go through it from now on."""
        self._pending.discard(pending)

    def _wait(
        self, future: Any, limit: float, what: str, watch: ServerWatch | None = None, *, on_shutdown: bool = True
    ) -> Any:
        """The future's result, waited for at most `limit` wall seconds (NavigatorTimeout naming `what` after).

        Raises ServerLost if `watch` finds the server gone first, and, if the ROS context is shut down meanwhile,
        ExternalShutdownException (see check_context), or _ContextShutDown without `on_shutdown`'s cancels.
        """

        def check() -> None:
            if on_shutdown:
                self.check_context(what)
            elif not self._node.context.ok():
                raise _ContextShutDown(what)
            reason = None if watch is None else watch.check()
            if reason is not None:
                raise ServerLost(reason)

        return wait_for_future(future, limit, what, NavigatorTimeout, check)

    def _watch(self, name: str) -> ServerWatch:
        return ServerWatch(self._in_use(name), name, self._timeouts().server_lost)

    def lost_code(self, name: str) -> int:
        """The error code of a goal whose server went away: the action's UNKNOWN code, as for a rejection."""
        action_type = self._types.get(name)
        return REJECTED_CODE if action_type is None else rejected_code(action_type)

    def check_context(self, what: str) -> None:
        """Raise ExternalShutdownException, after sending the running goals' cancels, if the node's context was
        shut down while its navigator still lives: rclpy's SIGINT/SIGTERM handler does that, and then nothing
        arrives any more (the spin thread has ended).

        Args:
            what: what the caller was waiting for, for the message.

        Raises:
            ExternalShutdownException: the context is shut down.
        """
        if self._node.context.ok():
            return
        said = "".join(f"; {_cancel_outcome(name, response)}" for name, response in self.cancel_after_shutdown())
        raise ExternalShutdownException(
            f"the ROS context was shut down (SIGINT or SIGTERM?) while waiting for {what}{said}"
        )

    def cancel_after_shutdown(self) -> list[tuple[str, Any]]:
        """Send the running goals' cancels (send_cancels) and wait at most CANCEL_WAIT in all for their answers
        (wait_for_cancel_answer): the caller goes on to end the process, which can take a request just written with
        it, and the goal then runs on. Returns (action name, the server's CancelGoal response, or None if none came
        in time) for each cancel sent."""
        deadline = time.monotonic() + CANCEL_WAIT
        return [(name, self.wait_for_cancel_answer(future, deadline)) for name, future in self.send_cancels()]

    def _cancel_answer(self, name: str, future: Any, watch: ServerWatch | None = None) -> Any:
        """The answer to a cancel of `name`'s goal, waited for as any reply (see _wait). Should the context be
        shut down meanwhile (rclpy's signal handler, racing the user's own handler that cancels), the spin thread
        has ended: the answer is taken by hand, for at most CANCEL_WAIT, and said in the log; None if none came."""
        try:
            return self._wait(
                future, self._timeouts().response, f"the '{name}' server to cancel", watch, on_shutdown=False
            )
        except _ContextShutDown:
            response = self.wait_for_cancel_answer(future, time.monotonic() + CANCEL_WAIT)
            self._say_after_shutdown(name, response)
            return response

    def _say_after_shutdown(self, name: str, response: Any) -> None:
        with contextlib.suppress(Exception):  # rclpy's logging may be finalized by now
            self._node.get_logger().warn(f"the ROS context is shut down: {_cancel_outcome(name, response)}")

    def send_cancels(self) -> list[tuple[str, Any]]:
        """Send a cancel for each running goal without waiting for the answers; returns (action name, the future
        its answer completes) for each.

        Takes no lock of ours and waits at most SIGNAL_LOCK_WAIT for a client's (a signal handler's helper thread
        calls it while the main thread, stopped where the signal found it, may hold one), and works after the
        context was shut down: the node and its clients still exist, and so do their DDS writers.
        """
        canceled = []
        for slot in (self.main, self.route):
            handle, client = slot.goal_handle, self._clients.get(slot.task_name)
            if handle is None or client is None or not slot.running():
                continue
            try:
                canceled.append((slot.task_name, client.cancel_goal_id_async(handle.goal_id, SIGNAL_LOCK_WAIT)))
            except Exception:  # noqa: BLE001 - best effort: a client already destroyed
                continue
        for pending in list(self._pending):  # sent, no handle yet: canceled by id (see the module docstring)
            try:
                canceled.append((pending.name, pending.cancel(SIGNAL_LOCK_WAIT)))
            except Exception:  # noqa: BLE001 - best effort: a client already destroyed
                continue
        return canceled

    def wait_for_cancel_answer(self, future: Any, deadline: float) -> Any:
        """Wait for the answer to a cancel, until the monotonic `deadline`; returns it (the CancelGoal response), or
        None if none came (or the request failed). The spin thread takes answers while the context lives; once the
        context is shut down (rclpy's signal handlers do it before the navigator's run) they are taken here
        (ActionClient.take_cancel_responses), under the same lock bound as send_cancels, and so are the answers to
        cancels send_cancels sent without a client's lock (the stopped thread holds it, and the spin thread waits
        for it). An answer proves the server has the cancel: a process that ends right after writing a request can
        take it with it."""
        while not future.done() and time.monotonic() < deadline:
            shut_down = not self._node.context.ok()
            for client in list(self._clients.values()):
                if shut_down or client.has_unlocked_cancels:
                    try:
                        client.take_cancel_responses(SIGNAL_LOCK_WAIT)
                    except Exception:  # noqa: BLE001 - best effort: a client already destroyed
                        continue
            if not future.done():
                time.sleep(0.01)
        if future.done():
            with contextlib.suppress(Exception):  # a failed request: it was sent all the same
                return future.result()
        return None

    def destroy(self) -> None:
        # rclpy's destroy takes a client out of the node's waitables, so the parked ones go back in first; without
        # `_creating`: the spin thread is stopped by now, and inside rclpy.shutdown() (which holds the context's
        # lock) it may wait for that lock while holding its turn, which `_creating` would then wait for
        for name in list(self._parked):
            self._parked.discard(name)
            self._node.add_waitable(self._clients[name])
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
            handle, pending = self._send(name, goal, on_feedback)
        except NavigatorTimeout as exc:
            self.error = (0, str(exc))
            raise
        try:
            with self._lock:
                if generation != slot.generation:  # another thread started a task meanwhile: it is the current one
                    return bool(handle.accepted)
                if not handle.accepted:
                    self.error = (rejected_code(self._types[name]), f"the '{name}' goal was rejected")
                    return False
                slot.goal_handle = handle
                slot.watch = self._watch(name)
                slot.done.clear()
                result_future = slot.result_future = handle.get_result_async()
        finally:
            self._sent(pending)
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
        """True when `slot` runs nothing or its task has finished; waits up to `wait` s for that to happen.

        Each turn also checks that the task's server is still there (a lost task ends ABORTED, see _liveness) and,
        when it waits, that the ROS context is not shut down (see check_context).
        """
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
            if not self._node.context.ok():
                if wait <= 0:  # a look at the status (getTaskStatusName) only reports
                    return False
                self.check_context(f"the '{slot.task_name}' goal's result")
            self.check_server(slot, generation)
            if slot.done.is_set():
                break
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                return False
            slot.done.wait(min(POLL_BACKSTOP, remaining))
        with self._lock:
            if generation == slot.generation:
                self.reported = slot
        return True

    def check_server(self, slot: TaskSlot, generation: int) -> None:
        """End the slot's goal ABORTED (task error: why) if its server went away (see _liveness)."""
        watch = slot.watch
        reason = None if watch is None else watch.check()
        if reason is not None:
            self._lose(slot, generation, reason)

    def _lose(self, slot: TaskSlot, generation: int, reason: str) -> None:
        with self._lock:
            if generation != slot.generation or slot.done.is_set():
                return
            slot.status = GoalStatus.STATUS_ABORTED
            slot.result = None
            self.error = (self.lost_code(slot.task_name), reason)
            self.finished_at = time.monotonic()
            handle, future, watch = slot.goal_handle, slot.result_future, slot.watch
            slot.done.set()
            if self.on_finished is not None:
                self.on_finished(slot)
        self._node.get_logger().error(reason)
        self._give_up(handle, future, watch)

    def _give_up(self, handle: Any, result_future: Any, watch: ServerWatch | None) -> None:
        """A lost goal: its cancel goes out anyway (a server that was only stalled must not drive on unwatched),
        and nothing waits for its answers any more."""
        pending = [result_future]
        if handle is not None:
            with contextlib.suppress(Exception):  # best effort
                pending.append(handle.cancel_goal_async())
        if watch is not None:
            watch.close()
            for future in pending:
                if future is not None and not future.done():
                    watch.client.forget_request(future)

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
        if not self._node.context.ok():  # the spin thread has ended (see check_context)
            answers = self.cancel_after_shutdown()
            for name, response in answers:
                self._say_after_shutdown(name, response)
            return any(response is not None and response.goals_canceling for _name, response in answers)
        accepted = False
        for pending in list(self._pending):  # a goal sent from another thread, its response not handled yet
            future = pending.cancel()
            with contextlib.suppress(NavigatorTimeout):  # the cancel went out; if accepted later, on_response
                response = self._cancel_answer(pending.name, future)
                accepted |= bool(response is not None and len(response.goals_canceling) > 0)
        for slot in (self.main, self.route):
            handle = slot.goal_handle
            if handle is None or not slot.running():
                continue
            generation = slot.generation
            self._before_send()
            future = handle.cancel_goal_async()
            try:
                response = self._cancel_answer(slot.task_name, future, slot.watch)
            except ServerLost as lost:  # the goal ends lost, not canceled
                self._lose(slot, generation, str(lost))
                continue
            accepted |= bool(response is not None and len(response.goals_canceling) > 0)
        return accepted

    # --- one-shot calls (planning, smoothing, routes, docking helpers) --------------------------------------------
    def call(self, name: str, goal: Any) -> tuple[int | None, Any]:
        """Send a goal and wait for its result, without touching the running tasks. (None, None) if rejected.

        A goal whose server goes away meanwhile ends ABORTED, its result the action's empty one (with the action's
        UNKNOWN code and the reason where it has those fields), and the task error says why.
        """
        handle, pending = self._send(name, goal, None)
        self._sent(pending)
        if not handle.accepted:
            return None, None
        limit = self._timeouts().result
        watch = self._watch(name)
        future = handle.get_result_async()
        try:
            response = self._wait(future, limit, f"the result of the '{name}' goal", watch)
        except ServerLost as lost:
            reason = str(lost)
            self.finished_at = time.monotonic()
            self.error = (self.lost_code(name), reason)
            self._node.get_logger().error(reason)
            self._give_up(handle, future, watch)
            result = self._types[name].Result()
            set_supported(result, error_code=self.error[0], error_msg=reason)
            return GoalStatus.STATUS_ABORTED, result
        self.finished_at = time.monotonic()
        watch.close()
        return int(response.status), response.result


def _error_of(result: Any, status: int) -> tuple[int, str]:
    code = int(getattr(result, "error_code", 0) or 0)
    msg = str(getattr(result, "error_msg", "") or "")
    if not msg and status == GoalStatus.STATUS_CANCELED:
        msg = "the task was canceled"
    return code, msg


def _cancel_outcome(name: str, response: Any) -> str:
    """What became of the cancel of `name`'s goal, for a message: `response` is its answer, or None."""
    if response is None:
        return f"the cancel of {name!r} was sent; no answer in {CANCEL_WAIT} s"
    if response.goals_canceling:
        return f"the cancel of {name!r} was sent and accepted"
    return f"the cancel of {name!r} was sent; its server had nothing left to cancel"
