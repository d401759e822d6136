"""Serving a core task as a ROS action: start it in the loop, relay feedback, map its end to the goal status.

Used by every action server of the simulator (Create 3 dock/undock and all Nav2 actions), so cancellation,
preemption and results behave the same everywhere.

Preemption: a robot runs one navigation task (and one Create 3 drive goal) at a time, so a new goal ends the
running one. Nav2's bt_navigator then aborts the old goal with an empty result (nav2_util's SimpleActionServer,
accept_pending_goal) and logs only "Received goal preemption request". Here the old goal also ends ABORTED, but
its result says why: the action's UNKNOWN code and "preempted by a newer <action> goal (goal <id>)", and the
simulator logs which goal preempted which. Goals are named by the first 4 bytes of their UUID in hex (the run
record's goal id is the same 4 bytes as a number): rclpy's action server sees no client identity, so a goal
replaced by its own client's next goal reads the same as one taken over by another client.
"""

from __future__ import annotations

import threading
import time
import weakref
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.duration import Duration
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile

from tb4.core.waits import wait_until
from tb4.ros.convert import fill_message, goal_poses
from tb4.ros.loop import LoopView
from tb4.ros.loop import task_done as is_done
from tb4.ros.qos import REQUESTS
from tb4.ros.replies import REPLY_READER_WAIT, wait_for_action_reply_readers, wait_for_feedback_readers
from tb4.ros.run_record import RobotRecord
from tb4.ros.stall_report import SlowDecisionReport
from tb4.wire import result_code

__all__ = [
    "TaskActionServer",
    "FEEDBACK_PERIOD",
    "is_done",
    "ImmediateTask",
    "GoalName",
    "RunningGoals",
    "running_goals",
    "short_goal_id",
    "preempted_message",
]

FEEDBACK_PERIOD = 0.05  # wall seconds between feedback messages (bounded rate whatever the sim speed)
_ACK_POLL = 0.005  # wall s between two looks at whether a goal's first feedback is acknowledged
# wall s between feedback messages while a goal's first is not acknowledged by every reader, REPLY_READER_WAIT at
# most (TaskActionServer._wait_for_acknowledgement): what a late client's side can miss meanwhile fits the writer's
# and the reader's default history of ten
HELD_FEEDBACK_PERIOD = 0.25
_NO_WAIT = Duration(nanoseconds=0)
# wall seconds a cancel naming a goal still being decided on waits for the decision (the goal callback waits up to
# REPLY_READER_WAIT for the client's reply reader)
CANCEL_DECISION_WAIT = REPLY_READER_WAIT + 3.0
# s a goal id canceled before its request came stays refused: a goal request late by more than this is not seen
CANCELED_UNSEEN_KEEP = 60.0
# goal ids kept so at most: a client sending cancels of random ids without end (a liveness probe does one now and
# then) must not grow the server; past it the oldest go first
CANCELED_UNSEEN_LIMIT = 1000
RCLError = _rclpy.RCLError


class _ActionServer(ActionServer):
    """rclpy's ActionServer, whose cancel request naming a goal still being decided on waits (bounded) for the
    decision, then cancels it if accepted; and which calls `on_cancels_marked()` once it has handled a cancel
    request.

    The simulator's executor has many threads: a goal request's callback (_on_goal) can still run in one while
    another takes a cancel request for that goal. rclpy then answers "unknown goal" and cancels nothing, and the
    goal, accepted a moment later, runs on. A client that lost track of its goal's acceptance (a signal, a goal
    response not yet handled or lost) cancels by the id it sent (tb4.navigator._task_client), and must not be
    answered that way. A single-threaded server (rclcpp's, Nav2's) decides each goal before it takes the next
    request, so a cancel sent after the goal always finds it.

    rclpy marks a goal CANCELING only after the cancel callback has returned, in the thread that took the request.
    A goal's task canceled from the callback can end, and its goal be ended, before that mark (that thread merely
    descheduled on a loaded machine): unmarked, the goal cannot end CANCELED, and the late mark then fails too, so
    the client hears its cancel refused. The owner cancels tasks in `on_cancels_marked` instead, after the marks.

    A cancel naming a goal id never seen can overtake its goal request (a client that sent its goal again under a
    new id cancels the silent send: tb4.ros.action_client); that goal is rejected when it comes, not run beside or
    over the goal sent again.

    Feedback goes out on a writer of this server's own (`feedback_writer`, on the action's feedback topic, with the
    action's feedback QoS), not on rcl_action's: only a writer of ours has a matched count, and a goal's first
    feedback waits until its client's feedback reader is matched (tb4.ros.replies.wait_for_feedback_readers).
    """

    def __init__(
        self,
        node: Node,
        action_type: Any,
        action_name: str,
        *args: Any,
        on_cancels_marked: Callable[[], None],
        **kwargs: Any,
    ) -> None:
        self._on_cancels_marked = on_cancels_marked
        self._deciding: Counter[bytes] = Counter()  # goal ids whose goal request is being handled
        self._deciding_lock = threading.Lock()
        self._canceled_unseen: dict[bytes, float] = {}  # goal id canceled before its request came -> when
        super().__init__(node, action_type, action_name, *args, **kwargs)
        self.feedback_writer = node.create_publisher(
            action_type.Impl.FeedbackMessage,
            f"{node.resolve_topic_name(action_name)}/_action/feedback",  # rcl_action resolves its name as a topic
            kwargs.get("feedback_pub_qos_profile", QoSProfile(depth=10)),  # rclpy's default for the action's own
        )

    def publish_feedback(self, goal_handle: ServerGoalHandle, feedback: Any) -> None:
        """Send `feedback` (the action's Feedback) for the goal of `goal_handle`, as ServerGoalHandle.publish_feedback
        does, on `feedback_writer`; nothing once the goal has ended."""
        if not goal_handle.is_active:
            return
        message = self._action_type.Impl.FeedbackMessage()
        message.goal_id = goal_handle.goal_id
        message.feedback = feedback
        self.feedback_writer.publish(message)

    def destroy(self) -> None:
        self._node.destroy_publisher(self.feedback_writer)
        super().destroy()

    async def _execute_goal_request(self, request_header_and_message: Any) -> None:
        request_header, request = request_header_and_message
        key = bytes(request.goal_id.uuid)
        with self._deciding_lock:
            overtaken = self._canceled_unseen.pop(key, None) is not None
            if not overtaken:
                self._deciding[key] += 1
        if overtaken:  # its client gave up on it and sent it again (tb4.ros.action_client): it must not run
            self._logger.warning(f"goal {short_goal_id(request.goal_id.uuid)} rejected: its cancel came before it")
            self._send_rejection(request_header)
            return
        try:
            await super()._execute_goal_request(request_header_and_message)
        finally:
            with self._deciding_lock:
                self._deciding[key] -= 1
                if self._deciding[key] <= 0:
                    del self._deciding[key]

    def _send_rejection(self, request_header: Any) -> None:
        """Reject a goal request without asking the goal callback (rclpy's own rejection, sent the same way)."""
        response = self._action_type.Impl.SendGoalService.Response()  # accepted False, zero stamp
        try:
            self._handle.send_goal_response(request_header, response)
        except RCLError:
            self._logger.warning("could not send a goal rejection (the client may have gone away)")

    def _remember_if_unseen(self, goal_info: Any) -> None:
        """A cancel naming one goal id that this server has never seen: its goal request may still be on its way
        (a client that sent its goal again drops the silent send this way), so that id is rejected if it comes
        within CANCELED_UNSEEN_KEEP seconds (the CANCELED_UNSEEN_LIMIT latest ids at most)."""
        stamp = goal_info.stamp
        key = bytes(goal_info.goal_id.uuid)
        if stamp.sec or stamp.nanosec or not any(key) or key in self._goal_handles:
            return
        now = time.monotonic()
        with self._deciding_lock:
            if key in self._deciding:
                return
            unseen = self._canceled_unseen  # oldest first (a dict keeps insertion order)
            unseen.pop(key, None)
            while unseen and (
                len(unseen) >= CANCELED_UNSEEN_LIMIT or now - next(iter(unseen.values())) > CANCELED_UNSEEN_KEEP
            ):
                del unseen[next(iter(unseen))]
            unseen[key] = now

    async def _execute_cancel_request(self, request_header_and_message: Any) -> None:
        key = bytes(request_header_and_message[1].goal_info.goal_id.uuid)
        wait_until(lambda: key not in self._deciding, CANCEL_DECISION_WAIT)
        self._remember_if_unseen(request_header_and_message[1].goal_info)
        try:
            await super()._execute_cancel_request(request_header_and_message)  # cancel callbacks, marks, response
        finally:
            self._on_cancels_marked()


@dataclass(frozen=True)
class GoalName:
    """How the simulator names a goal: its action and the first 4 bytes of its UUID, in hex."""

    action: str
    short_id: str

    def __str__(self) -> str:
        return f"{self.action} goal {self.short_id}"


def short_goal_id(uuid: Any) -> str:
    """What the simulator's log and results call a goal.

    Args:
        uuid: the goal's UUID (16 bytes, as unique_identifier_msgs/UUID.uuid holds them).

    Returns:
        Its first 4 bytes in hex.
    """
    return bytes(uuid[:4]).hex()


class RunningGoals:
    """The goals running on one robot across all its action servers, so that a goal ended by another goal's start
    is known as preempted, and by which goal. Starts run in the loop thread, ends on the servers' threads."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._running: dict[int, tuple[Any, GoalName]] = {}  # id(task) -> (task, its goal), while it runs
        self._preempted: dict[int, tuple[Any, GoalName]] = {}  # id(task) -> (task, the goal whose start ended it)

    def start(self, goal: GoalName, start: Callable[[], Any]) -> tuple[Any, list[GoalName]]:
        """Run `start()` (loop thread) for `goal`.

        Args:
            goal: the goal being started.
            start: builds and starts its task.

        Returns:
            The task, and the running goals its start ended (between two ticks nothing else ends a task).

        Raises:
            Exception: whatever `start()` raises (the goals it ended are noted all the same).
        """
        with self._lock:
            # a goal's thread forgets its task when it ends (finish); one that never got there is dropped here
            self._running = {key: entry for key, entry in self._running.items() if not is_done(entry[0])}
            before = list(self._running.values())
        ended: list[GoalName] = []
        try:
            task = start()
        finally:
            with self._lock:
                for old, name in before:
                    if is_done(old):
                        self._preempted[id(old)] = (old, goal)
                        ended.append(name)
        if not is_done(task):
            with self._lock:
                self._running[id(task)] = (task, goal)
        return task, ended

    def finish(self, task: Any) -> GoalName | None:
        """Forget an ended goal's task.

        Args:
            task: the task of the goal that ended.

        Returns:
            The goal whose start preempted it, or None when it ended otherwise.
        """
        with self._lock:
            self._running.pop(id(task), None)
            entry = self._preempted.pop(id(task), None)
        return entry[1] if entry is not None and entry[0] is task else None


#: one book of running goals per robot (keyed by the loop view's simulation, or the loop itself when it has none)
_ROBOT_GOALS: weakref.WeakKeyDictionary[Any, RunningGoals] = weakref.WeakKeyDictionary()
_ROBOT_GOALS_LOCK = threading.Lock()


def running_goals(loop: Any) -> RunningGoals:
    """The book of running goals of one robot, shared by all its action servers.

    Args:
        loop: the robot's loop view (its `sim` names the robot; a stand-in loop without one is its own robot).

    Returns:
        The robot's book, made at the first call.
    """
    key = getattr(loop, "sim", loop)
    with _ROBOT_GOALS_LOCK:
        book = _ROBOT_GOALS.get(key)
        if book is None:
            book = _ROBOT_GOALS[key] = RunningGoals()
        return book


def preempted_message(by: GoalName) -> str:
    """The error_msg of a preempted goal.

    Args:
        by: the goal whose start ended it.

    Returns:
        The message naming that goal.
    """
    return f"preempted by a newer {by.action} goal (goal {by.short_id}) from this or another client"


class ImmediateTask:
    """A request answered at once in the loop (planning, smoothing), served through the same action bridge."""

    def __init__(self, succeeded: bool, result: dict[str, Any]) -> None:
        self.status = "succeeded" if succeeded else "failed"
        self.done = True
        self._result = result

    @classmethod
    def failure(cls, error_code: int, error_msg: str, **fields: Any) -> ImmediateTask:
        """A request refused at once with the action's error code and a message saying why."""
        return cls(False, {"error_code": error_code, "error_msg": error_msg, **fields})

    def cancel(self) -> None:
        pass

    def feedback(self) -> dict[str, Any]:
        return {}

    def result(self) -> dict[str, Any]:
        return self._result


def _phase_feedback(task: Any) -> list[dict[str, Any]]:
    """The feedback of the moments a task marked since the last sample (tb4.nav.tasks.PhaseLog)."""
    drain = getattr(task, "drain_phase_feedback", None)
    return list(drain()) if drain is not None else []


class TaskActionServer:
    """An action server whose goals become core tasks.

    `start(goal_msg)` runs in the loop thread and returns the task (an object with `status`, `done()`,
    `cancel()`, `feedback()` and `result()`), or raises ValueError for a malformed goal, which is then
    aborted with the error in the result (code `invalid_code`, when the action has such a field).
    """

    def __init__(
        self,
        node: Node,
        loop: LoopView,
        action_type: Any,
        name: str,
        start: Callable[[Any], Any],
        *,
        stamp: Callable[[], float],
        invalid_code: int | None = None,
        result_fields: Callable[[Any], dict[str, Any]] | None = None,
        feedback_fields: Callable[[Any], dict[str, Any]] | None = None,
        accept: Callable[[Any], bool] | None = None,
        record: RobotRecord | None = None,
    ) -> None:
        self._record = record
        self._tasks: dict[bytes, tuple[Any, Any]] = {}  # running goals' (task, goal handle), by goal id
        self._cancels_sent: set[bytes] = set()  # goal ids of _tasks whose task's cancel went to the loop
        self._cancel_lock = threading.Lock()  # _tasks and _cancels_sent change together
        self.loop = loop
        self.action_type = action_type
        self.name = name
        self._start = start
        self._stamp = stamp
        self._invalid_code = invalid_code
        self._result_fields = result_fields or (lambda task: task.result())
        self._feedback_fields = feedback_fields or (lambda task: task.feedback())
        self._logger = node.get_logger()
        self._node = node
        self._accept = accept
        self._action_name = node.resolve_service_name(name)
        self._goals = running_goals(loop)
        try:
            self._preempted_code: int | None = result_code(action_type, "UNKNOWN")
        except (KeyError, AttributeError):  # the Create 3's results carry no error code
            self._preempted_code = None
        self.server = _ActionServer(
            node,
            action_type,
            name,
            execute_callback=self._execute,
            goal_callback=self._on_goal,
            cancel_callback=self._on_cancel,
            callback_group=ReentrantCallbackGroup(),
            goal_service_qos_profile=REQUESTS,
            result_service_qos_profile=REQUESTS,
            cancel_service_qos_profile=REQUESTS,
            on_cancels_marked=self._cancel_marked_tasks,
        )

    def _on_goal(self, goal: Any) -> GoalResponse:
        with SlowDecisionReport(f"a {self.name} goal", self._logger.warning):
            return self._decide(goal)

    def _decide(self, goal: Any) -> GoalResponse:
        # rclpy sends the goal response right after this returns: hold it until a new client can read it
        wait_for_action_reply_readers(self._node, self._action_name, "send_goal")
        if self._accept is None:
            return GoalResponse.ACCEPT
        try:
            accepted = self._accept(goal)
        except Exception as exc:  # noqa: BLE001 - rclpy sends no response at all when this raises
            # A goal callback that raises leaves the client waiting for a goal response that never comes (rclpy
            # ends the request's task with the exception); a rejection with the reason logged answers it.
            self._logger.error(f"{self.name} goal rejected: deciding on it failed ({type(exc).__name__}: {exc})")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT if accepted else GoalResponse.REJECT

    def _on_cancel(self, goal_handle: Any) -> CancelResponse:
        # the task is canceled once rclpy has marked the goal CANCELING (_cancel_marked_tasks), not here: see
        # _ActionServer
        return CancelResponse.ACCEPT

    def _cancel_marked_tasks(self) -> None:
        """Cancel the tasks of the goals rclpy has marked CANCELING, each once (the cancel request's thread, after
        the marks). A goal's task ended by its cancel then always finds its goal marked, and ends it CANCELED."""
        with self._cancel_lock:
            due = [
                (key, task)
                for key, (task, goal_handle) in self._tasks.items()
                if key not in self._cancels_sent and goal_handle.is_cancel_requested
            ]
            self._cancels_sent.update(key for key, _task in due)
        for _key, task in due:
            self.loop.inputs.cancel(task)  # the loop cancels it between two ticks

    def _note_result(self, status: str, result: Any, goal_id: int, error_msg: str = "") -> None:
        """The result in the run record; `error_msg` says why where the action's result has no such field."""
        if self._record is not None:
            self._record.result(
                self.name,
                self._stamp(),
                status,
                goal_id,
                int(getattr(result, "error_code", 0) or 0),
                str(getattr(result, "error_msg", "") or error_msg),
            )

    def _start_goal(self, goal_handle: Any) -> Any:
        """Start the goal's task (loop thread); the running goals its start ended are logged as preempted."""
        goal = GoalName(self.name, short_goal_id(goal_handle.goal_id.uuid))
        task, ended = self._goals.start(goal, lambda: self._start(goal_handle.request))
        for old in ended:
            self._logger.info(f"{old} preempted by the newer {goal}: it ends ABORTED (one goal runs at a time)")
        return task

    def _publish_feedback(self, goal_handle: Any, batch: list[dict[str, Any]]) -> bool:
        """Send `batch`; whether anything went out."""
        for fields in batch:
            self.server.publish_feedback(goal_handle, fill_message(self.action_type.Feedback(), fields, self._stamp()))
        return bool(batch)

    def _wait_for_acknowledgement(self, finished: threading.Event, timeout: float) -> bool:
        """Wait at most `timeout` s (less once the goal has ended) until every matched reader has acknowledged all the
        feedback sent; whether they have.

        A goal's later feedback is slowed to HELD_FEEDBACK_PERIOD until its first is acknowledged (at most
        REPLY_READER_WAIT s), before more can push it out of the writer's history. A reader is matched on this side
        (wait_for_feedback_readers) before the client's side has matched this writer, and what the client's side
        misses meanwhile is repaired only from that history (rclpy's default keeps ten): a stress run lost a stock
        client's first feedback that way, its executor never stalled. Slowed, not stopped: the writer's
        acknowledgement is every reader's, and a reader that never acknowledges held every other client's feedback
        for the whole bound (a short drive sent its first message and no other). Readers acknowledge on the writer's
        heartbeat: the simulator's DDS profile sends one every 0.1 s (tb4.rosenv.apply_simulator_dds_profile), Fast
        DDS's default every 3 s. Polled without waiting: a drive stood still through a blocking wait_for_all_acked of
        2 s (rclpy keeps the GIL in it), the whole simulator with it."""
        writer = self.server.feedback_writer
        acknowledged = False

        def done() -> bool:
            nonlocal acknowledged
            acknowledged = writer.wait_for_all_acked(_NO_WAIT)
            return acknowledged or finished.is_set()

        wait_until(done, timeout, period=_ACK_POLL)
        return acknowledged

    def _finish_invalid(self, goal_handle: Any, message: str) -> Any:
        self._logger.warn(f"{self.name}: {message}")
        result = self.action_type.Result()
        fields: dict[str, Any] = {"error_msg": message}
        if self._invalid_code is not None:
            fields["error_code"] = self._invalid_code
        fill_message(result, fields)
        goal_handle.abort()
        return result

    def _execute(self, goal_handle: Any) -> Any:
        result = self._run_goal(goal_handle)
        # rclpy sends the result right after this returns: hold it until the client can read it (see replies)
        wait_for_action_reply_readers(self._node, self._action_name, "get_result")
        return result

    def _run_goal(self, goal_handle: Any) -> Any:
        # a new client must get the goal's first feedback
        wait_for_feedback_readers(self._node, self._action_name, self.server.feedback_writer)
        self.loop.release()
        goal_id = int.from_bytes(bytes(goal_handle.goal_id.uuid[:4]), "big")
        if self._record is not None:
            self._record.goal(self.name, self._stamp(), goal_poses(goal_handle.request), goal_id)
        try:
            task = self.loop.call(lambda: self._start_goal(goal_handle))
        except (ValueError, TypeError) as exc:
            result = self._finish_invalid(goal_handle, str(exc))
            self._note_result("failed", result, goal_id)
            return result
        except Exception as exc:  # the simulator is shutting down, or a bug: fail this goal, keep serving
            result = self._finish_invalid(goal_handle, f"internal error: {exc}")
            self._note_result("failed", result, goal_id)
            return result

        key = bytes(goal_handle.goal_id.uuid)
        with self._cancel_lock:
            self._tasks[key] = (task, goal_handle)
            # marked before the task existed: its cancel request's _cancel_marked_tasks may have come and gone
            canceled_before = goal_handle.is_cancel_requested
            if canceled_before:
                self._cancels_sent.add(key)
        finished = self.loop.watch(task)  # set by the loop when the task ends: no polling
        held_until: float | None = None  # while the first feedback is not acknowledged: until when it slows the rest
        try:
            if canceled_before:
                self.loop.inputs.cancel(task)
            while not finished.wait(FEEDBACK_PERIOD):
                if not self.loop.running:
                    with self.loop.lock:
                        task.cancel()
                    break
                with self.loop.lock:
                    batch = _phase_feedback(task)
                    current = None if is_done(task) else self._feedback_fields(task)  # None: nothing new to say
                    if current is not None:
                        batch.append(current)
                if self._publish_feedback(goal_handle, batch) and held_until is None:
                    held_until = time.monotonic() + REPLY_READER_WAIT
                if held_until is not None and (left := held_until - time.monotonic()) > 0:
                    wait = min(left, HELD_FEEDBACK_PERIOD - FEEDBACK_PERIOD)
                    if self._wait_for_acknowledgement(finished, wait):
                        held_until = 0.0  # acknowledged: the rest goes at FEEDBACK_PERIOD
            with self.loop.lock:
                batch = _phase_feedback(task)  # phases entered since the last sample, the last one included
            self._publish_feedback(goal_handle, batch)
        finally:
            with self._cancel_lock:
                self._tasks.pop(key, None)
                self._cancels_sent.discard(key)
            preempted_by = self._goals.finish(task)

        with self.loop.lock:
            status = task.status
            fields = self._result_fields(task)
        reason = ""
        if status == "succeeded":
            end = goal_handle.succeed
        elif status == "canceled" and goal_handle.is_cancel_requested:  # a client asked (_cancel_marked_tasks)
            end = goal_handle.canceled
        else:
            end = goal_handle.abort
            if preempted_by is not None:
                reason = preempted_message(preempted_by)
                fields = {**fields, "error_code": self._preempted_code, "error_msg": reason}
        result = fill_message(self.action_type.Result(), fields, self._stamp())
        self._note_result(status, result, goal_id, reason)
        end()
        return result
