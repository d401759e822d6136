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

For telling a live server from a dead one, `last_heard` says when the server last sent this client anything (a
goal's feedback or status, any reply), and `probe_async` asks it a question every live action server answers at
once: a process killed hard stays in the ROS graph until its DDS lease runs out (Fast DDS: 20 s), so the graph
alone is slow to tell.

Its goal, result and cancel replies are read with tb4.ros.qos.REQUESTS (a deep queue), as every server of ours
reads requests: with rclpy's default depth of 10, a client that took its replies more slowly than a burst of goals
brought them lost goal responses for good.

Use this class for every action client.
"""

from __future__ import annotations

import time
from typing import Any

from action_msgs.srv import CancelGoal
from rclpy.action import ActionClient as _RclpyActionClient
from rclpy.task import Future

from tb4.ros.qos import REQUESTS

__all__ = ["ActionClient", "LATE_FEEDBACK_GRACE"]

# s a goal's feedback callback outlives its result: a starved client (one message per wake-up) can still be taking
# that goal's queued feedback many seconds after the result is in (a stress run's route test never saw its arrival
# feedback with 5 s here; the last one it had taken was an early one)
LATE_FEEDBACK_GRACE = 30.0
_REPLY_QUEUES = ("goal_service_qos_profile", "result_service_qos_profile", "cancel_service_qos_profile")


class ActionClient(_RclpyActionClient):
    """rclpy.action.ActionClient whose send_goal_async returns the future the goal response completes, and whose
    feedback callbacks outlive their goal's result by LATE_FEEDBACK_GRACE seconds."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        for queue in _REPLY_QUEUES:  # deep reply queues unless the caller chose (tb4.ros.qos.REQUESTS says why)
            kwargs.setdefault(queue, REQUESTS)
        super().__init__(*args, **kwargs)
        self._feedback_expiry: dict[bytes, float] = {}  # finished goal's uuid -> when its callback goes
        #: monotonic time the server last sent this client anything (feedback, status, a reply); creation before
        self.last_heard = time.monotonic()

    async def execute(self, taken_data: Any) -> None:
        if taken_data:
            self.last_heard = time.monotonic()
        await super().execute(taken_data)

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
                not awaited: the returned future never completes.

        Returns:
            A future completed by the server's CancelGoal response.
        """
        request = CancelGoal.Request()
        request.goal_info.goal_id = goal_id  # stamp stays zero: this goal id only
        future: Future = Future()
        if not self._lock.acquire(timeout=lock_timeout):
            # the holder is stopped where the signal found it: the client's handle is not in use meanwhile
            self._client_handle.send_cancel_request(request)
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

    def send_goal_async(self, goal: Any, feedback_callback: Any = None, goal_uuid: Any = None) -> Future:
        if not isinstance(goal, self._action_type.Goal):
            raise TypeError(f"Expected goal type ({type(self._action_type.Goal)}) but received ({type(goal)})")
        request = self._action_type.Impl.SendGoalService.Request()
        request.goal_id = self._generate_random_uuid() if goal_uuid is None else goal_uuid
        request.goal = goal
        uuid = bytes(request.goal_id.uuid)
        self._forget_expired_feedback(time.monotonic())
        if feedback_callback is not None:  # before sending: feedback may come as soon as the goal is accepted
            self._feedback_callbacks[uuid] = feedback_callback
        future: Future = Future()
        try:
            with self._lock:  # the executor takes responses under this lock: the future is in place before that
                sequence_number = self._client_handle.send_goal_request(request)
                if sequence_number in self._pending_goal_requests:
                    raise RuntimeError(f"Sequence ({sequence_number}) conflicts with pending goal request")
                self._pending_goal_requests[sequence_number] = future
                self._goal_sequence_number_to_goal_id[sequence_number] = request.goal_id
                future.add_done_callback(self._remove_pending_goal_request)
                self.add_future(future)  # so the executor knows of it
        except BaseException:
            self._feedback_callbacks.pop(uuid, None)
            raise
        return future
