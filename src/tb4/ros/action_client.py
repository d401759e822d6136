"""rclpy's ActionClient, with the goal-response race of rclpy 9.1.2 (the Kilted wheels) closed, and a goal's
feedback still delivered when it comes in after the goal's result.

rclpy 9.1.2's `send_goal_async` registers the goal's future under the client's lock, releases the lock, then
builds a second future, registers it under the same sequence number and returns that one. When the executor
thread takes the goal response in between (the script's thread sends while a background thread spins, as in every
client of ours), the first future gets the goal handle and the returned one never completes: the script waits for
an acceptance that already came ("timed out ... waiting for the server to accept or reject the goal"). A loaded
machine preempts the sending thread inside that gap. Here the one future is registered with the request, under
the lock, so the executor cannot take the response before the future exists.

rclpy also drops a goal's feedback callback as soon as its result is in. The server sends the last feedback
before the result, but on another topic: the client can take the result first (under load it often does), and
the goal's last feedback (the arrival, the last waypoint, the docking's final phase) is then thrown away. Here a
finished goal's callback lives LATE_FEEDBACK_GRACE seconds longer; callers that must tell goals apart already do
(the navigator numbers its goals and ignores an earlier goal's feedback).

rclpy 7 (ROS 2 Jazzy) has the same gap without any lock, for its cancel and result requests too: it sends the
request, then registers the future, and takes responses unlocked. A response taken in between is dropped ("Ignoring
unexpected cancel response") and the future never completes: a caller waits for it in vain. There this
class brings the lock (a compatibility point, the one difference of rclpy 7 it needs): responses are taken under
it, as rclpy 9 takes them, and goal, cancel and result requests are sent and registered under it, as rclpy 9 does.

For telling a live server from a dead one, `last_heard` says when the server last sent this client anything (a
goal's feedback or status, any reply), and `probe_async` asks it a question every live action server answers at
once: a process killed hard stays in the ROS graph until its DDS lease runs out (Fast DDS: 20 s), so the graph
alone is slow to tell.

Its goal, result and cancel replies are read with tb4.ros.qos.REQUESTS (a deep queue), as every server of ours
reads requests: with rclpy's default depth of 10, a client that took its replies more slowly than a burst of goals
brought them lost goal responses for good.

A goal whose goal response does not come is sent again. On a loaded machine a first goal of a brand-new client
was, now and then, never answered: the server's log showed no request at all, while the client had seen the server
in the graph and matched its request reader (stress runs of the whole suite lost bump_and_go's undock this
way). A send still unanswered after GOAL_RESEND_AFTER seconds is canceled by its id and the goal goes again under a
new id, GOAL_SENDS times at most, within the caller's own bound. A new id, not the same one: rclcpp's action server
(Nav2's, the Create 3's) accepts a repeated goal id in its goal callback, then throws from its executor when it
registers the goal, so a repeated id could take down the very server it asks. The cost of a new id is a goal
answered after all, just late: that send's goal is canceled when its acceptance comes (tb4's own servers also
reject a goal whose cancel came first, tb4.ros.action_bridge). A client whose executor took nothing for that long
(its response waiting, untaken) restarts its goal so: the first send is canceled and the second runs. tb4's clients
spin in a thread of their own, where a take waits milliseconds.

Use this class for every action client.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

from action_msgs.srv import CancelGoal
from rclpy.action import ActionClient as _RclpyActionClient
from rclpy.task import Future

from tb4.ros.qos import REQUESTS
from tb4.ros.replies import counted, dds_topic, service_graph_report

__all__ = [
    "ActionClient",
    "BUILT_LAST",
    "GOAL_RESEND_AFTER",
    "GOAL_SENDS",
    "GoalSend",
    "LATE_FEEDBACK_GRACE",
    "RCLPY_TAKES_UNDER_LOCK",
]

#: Whether rclpy's ActionClient has a lock of its own (rclpy 9, Kilted) or not (rclpy 7, Jazzy: ours brings one).
RCLPY_TAKES_UNDER_LOCK = "_lock" in _RclpyActionClient.__init__.__code__.co_names
#: The attribute rclpy's ActionClient.__init__ sets last, after it has registered the client with its node: a client
#: without it is still being built, and an executor must not touch it. rclpy 9 sets its lock last, rclpy 7 its logger.
BUILT_LAST = "_lock" if RCLPY_TAKES_UNDER_LOCK else "_logger"

# s a goal's feedback callback outlives its result: a starved client (one message per wake-up) can still be taking
# that goal's queued feedback many seconds after the result is in (a stress run's route test never saw its arrival
# feedback with 5 s here; the last one it had taken was an early one)
LATE_FEEDBACK_GRACE = 30.0
#: s a send waits for its goal response before the goal goes again under a new id: far beyond any answer seen from a
#: live server on a loaded machine, well inside the navigator's response limit (tb4.navigator.timeouts)
GOAL_RESEND_AFTER = 4.0
#: sends of one goal at most (the first included)
GOAL_SENDS = 3
_REPLY_QUEUES = ("goal_service_qos_profile", "result_service_qos_profile", "cancel_service_qos_profile")


def _complete(future: Future | None, response: Any) -> None:
    """Complete a request's future with its answer taken outside the executor, unless it is done or unknown."""
    if future is not None and not future.done():
        # done before its callbacks are scheduled, which the executor may refuse once its context is down
        with contextlib.suppress(Exception):
            future.set_result(response)


class ActionClient(_RclpyActionClient):
    """rclpy.action.ActionClient whose send_goal_async returns the future the goal response completes, and whose
    feedback callbacks outlive their goal's result by LATE_FEEDBACK_GRACE seconds."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        for queue in _REPLY_QUEUES:  # deep reply queues unless the caller chose (tb4.ros.qos.REQUESTS says why)
            kwargs.setdefault(queue, REQUESTS)
        super().__init__(*args, **kwargs)
        if not RCLPY_TAKES_UNDER_LOCK:  # rclpy 7 (Jazzy) has no lock: ours, taken in take_data (see the module)
            self._lock = threading.Lock()
        self._feedback_expiry: dict[bytes, float] = {}  # finished goal's uuid -> when its callback goes
        # cancels sent without the lock (cancel_goal_id_async): sequence number -> the future their answer completes
        self._unlocked_cancels: dict[int, Future] = {}
        #: monotonic time the server last sent this client anything (feedback, status, a reply); creation before
        self.last_heard = time.monotonic()

    def take_data(self) -> Any:
        # "in vars": the executor may ask before __init__ is through (the client is registered in rclpy's __init__)
        if not RCLPY_TAKES_UNDER_LOCK and "_lock" in vars(self):
            with self._lock:
                return super().take_data()
        return super().take_data()

    def _cancel_goal_async(self, goal_handle: Any) -> Future:
        if RCLPY_TAKES_UNDER_LOCK:  # rclpy 9 sends and registers under its own lock
            return super()._cancel_goal_async(goal_handle)
        with self._lock:  # rclpy 7 registers the future after the send, unlocked (see the module)
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle: Any) -> Future:
        if RCLPY_TAKES_UNDER_LOCK:
            return super()._get_result_async(goal_handle)
        with self._lock:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data: Any) -> None:
        if taken_data:
            self.last_heard = time.monotonic()
        if taken_data and "cancel" in taken_data and taken_data["cancel"][0] in self._unlocked_cancels:
            sequence_number, response = taken_data.pop("cancel")  # rclpy would drop it as unexpected
            _complete(self._unlocked_cancels.pop(sequence_number, None), response)
        await super().execute(taken_data)

    def graph_report(self) -> str:
        """What this node's view of the graph shows of the action's server, for an error that says why the server is
        not ready: per service, its request readers and reply writers (rmw_fastrtps calls a server available only
        when the two counts are equal and this client has matched both), and the feedback and status writers.

        Returns:
            One line, e.g. "send_goal: 1 request reader, 1 reply writer; ...; status: 1 writer".
        """
        node = self._node
        name = node.resolve_topic_name(self._action_name)
        parts = []
        for service in ("send_goal", "cancel_goal", "get_result"):
            parts.append(f"{service}: {service_graph_report(node, f'{name}/_action/{service}')}")
        for topic in ("feedback", "status"):
            writers = len(node.get_publishers_info_by_topic(dds_topic(f"{name}/_action/{topic}"), no_mangle=True))
            parts.append(f"{topic}: {counted(writers, 'writer')}")
        return "; ".join(parts)

    def _server_state(self) -> str:
        """Whether rmw calls the server ready, and the graph_report: a goal response missing from a ready server
        was lost or left untaken on this side, one from a server gone from the graph was never sent."""
        try:
            ready = "yes" if self.server_is_ready() else "no"
            return f"the server is ready: {ready}; the graph shows {self.graph_report()}"
        except Exception as exc:  # noqa: BLE001 - a node being destroyed: the warning goes out all the same
            return f"the server's state unknown ({type(exc).__name__}: {exc})"

    def probe_async(self) -> Future:
        """Ask the server to cancel a goal id it has never seen, and return the future its answer completes.

        No server knows a fresh random id: it cancels nothing and is answered at once (ERROR_UNKNOWN_GOAL_ID), by
        any live server. A result request for an unknown goal would be answered as readily, but rclpy's server logs
        a warning for each.

        Returns:
            A future completed by the server's CancelGoal response (its answer updates `last_heard` too).
        """
        return self.cancel_goal_id_async(self._generate_random_uuid())

    def new_goal_id(self) -> Any:
        """A fresh random goal id (unique_identifier_msgs/UUID), to send a goal with (send_goal_async's
        `goal_uuid`) when it may have to be canceled before its goal response is in."""
        return self._generate_random_uuid()

    def cancel_goal_id_async(self, goal_id: Any, lock_timeout: float = -1) -> Future:
        """Ask the server to cancel the goal with this id, whether or not this client has its goal handle yet.

        A cancel request naming one goal, with a zero stamp, cancels that goal only (rcl_action, under rclpy's and
        rclcpp's servers alike). A server that has not accepted the goal (yet) answers ERROR_UNKNOWN_GOAL_ID and
        cancels nothing.

        Args:
            goal_id: the goal's unique_identifier_msgs/UUID, as sent in its SendGoal request.
            lock_timeout: seconds to wait for the client's lock (negative: as long as it takes). A signal handler's
                helper passes a bound: the thread the signal interrupted may hold the lock (inside send_goal_async)
                and wait for the helper. Past the bound the request is sent without the lock, and its answer is
                taken without it too (take_cancel_responses), or by the executor once the lock is free.

        Returns:
            A future completed by the server's CancelGoal response.
        """
        request = CancelGoal.Request()
        request.goal_info.goal_id = goal_id  # stamp stays zero: this goal id only
        future: Future = Future()
        if not self._lock.acquire(timeout=lock_timeout):
            # the holder is stopped where the signal found it: the client's handle is not in use meanwhile
            self._unlocked_cancels[self._client_handle.send_cancel_request(request)] = future
            return future
        try:
            sequence_number = self._client_handle.send_cancel_request(request)
            if sequence_number in self._pending_cancel_requests:
                raise RuntimeError(f"Sequence ({sequence_number}) conflicts with pending cancel request")
            self._pending_cancel_requests[sequence_number] = future
            future.add_done_callback(self._remove_pending_cancel_request)
            self.add_future(future)
        finally:
            self._lock.release()
        return future

    def take_cancel_responses(self, lock_timeout: float) -> None:
        """Take the cancel responses that have come in and complete their futures, without an executor.

        For a signal's handler: rclpy shuts the context down before our handler runs, and the spin thread then
        takes nothing. A process that ends as soon as its cancel is written can end before the request has left
        (it dies with its writer, and the robot drives on); an answer taken here proves the server has the cancel.
        The client's DDS entities outlive the context's shutdown, so a take still works.

        The same is needed while the context lives when the thread the signal stopped holds the client's lock
        (it was sending a goal): the spin thread then waits for that lock to take anything, for as long as the
        handler runs. A cancel sent without the lock (cancel_goal_id_async) is answered here without it too.

        Args:
            lock_timeout: seconds to wait for the client's lock (the thread the signal stopped may hold it); past
                it only the answers to cancels sent without the lock are taken, without it.
        """
        taken: list[tuple[int, Any]] = []
        locked = self._lock.acquire(timeout=lock_timeout)
        if not locked and not self._unlocked_cancels:
            return
        try:
            while True:
                sequence_number, response = self._client_handle.take_cancel_response(
                    self._action_type.Impl.CancelGoalService.Response
                )
                if sequence_number is None or response is None:  # nothing (more) to take
                    break
                taken.append((sequence_number, response))
        finally:
            if locked:
                self._lock.release()
        for sequence_number, response in taken:
            pending = self._pending_cancel_requests.pop(sequence_number, None)
            _complete(pending if pending is not None else self._unlocked_cancels.pop(sequence_number, None), response)

    @property
    def has_unlocked_cancels(self) -> bool:
        """Whether a cancel sent without the client's lock still waits for its answer (take_cancel_responses)."""
        return bool(self._unlocked_cancels)

    def forget_request(self, future: Future) -> None:
        """Stop waiting for a probe's or a result's answer (a server that went away never sends it)."""
        self._remove_pending_cancel_request(future)
        self._remove_pending_result_request(future)

    def _remove_pending_result_request(self, future: Future) -> None:
        """rclpy's clean-up once a result is in, except that the goal's feedback callback stays a while."""
        callbacks = dict(self._feedback_callbacks)
        super()._remove_pending_result_request(future)
        now = time.monotonic()
        for uuid in callbacks.keys() - self._feedback_callbacks.keys():
            self._feedback_callbacks[uuid] = callbacks[uuid]
            self._feedback_expiry[uuid] = now + LATE_FEEDBACK_GRACE
        self._forget_expired_feedback(now)

    def _forget_expired_feedback(self, now: float) -> None:
        for uuid, expiry in list(self._feedback_expiry.items()):
            if expiry <= now:
                self._feedback_expiry.pop(uuid, None)
                self._feedback_callbacks.pop(uuid, None)

    def send_goal_async(self, goal: Any, feedback_callback: Any = None, goal_uuid: Any = None) -> GoalSend:
        """Send a goal; the returned future is completed by its goal response (a ClientGoalHandle).

        A goal response that has not come GOAL_RESEND_AFTER seconds after a send makes the goal go again, under a
        new goal id, at most GOAL_SENDS times in all (see the module docstring). Only the latest send's response
        completes the future; an earlier send is canceled by its id when the goal goes again, and its handle is
        canceled if it is accepted after all.

        Args:
            goal: the action's Goal message.
            feedback_callback: called with each feedback message of the goal (whichever send is current).
            goal_uuid: the id of the first send (a unique_identifier_msgs/UUID); a random one if None.

        Returns:
            A GoalSend: the future, and `goal_ids`, every id the goal has been sent under so far.

        Raises:
            TypeError: `goal` is not this action's Goal.
        """
        if not isinstance(goal, self._action_type.Goal):
            raise TypeError(f"Expected goal type ({type(self._action_type.Goal)}) but received ({type(goal)})")
        self._forget_expired_feedback(time.monotonic())
        send = GoalSend(goal, feedback_callback)
        self._send_once(send, self._generate_random_uuid() if goal_uuid is None else goal_uuid)
        return send

    def _send_once(self, send: GoalSend, goal_id: Any) -> None:
        """Send `send`'s goal under `goal_id`, and arm its resend."""
        request = self._action_type.Impl.SendGoalService.Request()
        request.goal_id = goal_id
        request.goal = send.goal
        uuid = bytes(goal_id.uuid)
        if send.feedback_callback is not None:  # before sending: feedback may come as soon as the goal is accepted
            self._feedback_callbacks[uuid] = send.feedback_callback
        answer: Future = Future()
        try:
            with self._lock:  # the executor takes responses under this lock: the future is in place before that
                sequence_number = self._client_handle.send_goal_request(request)
                if sequence_number in self._pending_goal_requests:
                    raise RuntimeError(f"Sequence ({sequence_number}) conflicts with pending goal request")
                self._pending_goal_requests[sequence_number] = answer
                self._goal_sequence_number_to_goal_id[sequence_number] = request.goal_id
                answer.add_done_callback(self._remove_pending_goal_request)
                self.add_future(answer)  # so the executor knows of it
                send.goal_ids.append(goal_id)
        except BaseException:
            self._feedback_callbacks.pop(uuid, None)
            raise
        answer.add_done_callback(lambda done: self._on_goal_answer(send, goal_id, done))
        if len(send.goal_ids) < GOAL_SENDS:
            send.arm(GOAL_RESEND_AFTER, lambda: self._resend(send, goal_id))

    def _resend(self, send: GoalSend, silent_id: Any) -> None:
        """The resend timer: `silent_id` got no goal response in time; cancel it by its id and send again."""
        with send.lock:  # an answer taken meanwhile decides first (_on_goal_answer)
            if send.stopped or send.done() or send.goal_ids[-1] is not silent_id or self._client_handle is None:
                return
            self._logger.warning(
                f"no goal response from '{self._action_name}' {GOAL_RESEND_AFTER:g} s after the goal was sent: "
                f"sending it again under a new goal id (the silent one is canceled); {self._server_state()}"
            )
            try:
                self.cancel_goal_id_async(silent_id)
                self._send_once(send, self._generate_random_uuid())
            except Exception as exc:  # noqa: BLE001 - a client destroyed meanwhile: the caller's bound reports it
                self._logger.warning(f"could not send the goal to '{self._action_name}' again: {exc}")

    def _on_goal_answer(self, send: GoalSend, goal_id: Any, answer: Future) -> None:
        """A send's goal response (or its future's end): the latest send's completes `send`; an earlier send's
        goal, accepted after all, is canceled (it would run beside the latest, or preempt it)."""
        with send.lock:
            latest = send.goal_ids[-1] is goal_id
            send.stopped = send.stopped or latest
        if latest:
            send.disarm()
            for earlier in send.goal_ids[:-1]:  # their feedback is not the caller's any more
                self._feedback_callbacks.pop(bytes(earlier.uuid), None)
            if send.done():
                return
            error = None if answer.cancelled() else answer.exception()
            if answer.cancelled():
                send.cancel()
            elif error is not None:
                send.set_exception(error)
            else:
                send.set_result(answer.result())
            return
        self._feedback_callbacks.pop(bytes(goal_id.uuid), None)
        handle = None if answer.cancelled() or answer.exception() is not None else answer.result()
        if handle is not None and handle.accepted:
            self._logger.warning(f"a goal of '{self._action_name}' sent again was accepted late too: canceling it")
            send.late_handles.append(handle)  # the client keeps only a weak reference until the cancel is through
            handle.cancel_goal_async()


class GoalSend(Future):
    """The future ActionClient.send_goal_async returns, completed by the goal response of the goal's latest send.

    Attributes:
        goal_ids: every goal id the goal has been sent under (unique_identifier_msgs/UUID), the latest last; a
            cancel by id made before the goal response is in must name each.
    """

    def __init__(self, goal: Any, feedback_callback: Any) -> None:
        super().__init__()
        self.goal = goal
        self.feedback_callback = feedback_callback
        self.goal_ids: list[Any] = []
        self.late_handles: list[Any] = []
        self.lock = threading.RLock()  # orders a resend against the latest send's answer (a resend arms under it)
        self.stopped = False  # no more sends: the latest send's goal response is in, or the caller said so
        self._timer: threading.Timer | None = None
        self.add_done_callback(lambda _done: self.disarm())

    def arm(self, after: float, resend: Any) -> None:
        """Call `resend` in `after` seconds, unless disarmed first (one timer at a time); nothing once stopped."""
        timer = threading.Timer(after, resend)
        timer.daemon = True
        with self.lock:  # the latest send's answer can stop this goal from the executor's thread meanwhile
            if self.stopped:
                return
            previous, self._timer = self._timer, timer
        if previous is not None:
            previous.cancel()
        timer.start()

    def stop_resending(self) -> None:
        """Send the goal no more (a caller that cancels it by its ids first)."""
        with self.lock:
            self.stopped = True
        self.disarm()

    def disarm(self) -> None:
        with self.lock:
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
