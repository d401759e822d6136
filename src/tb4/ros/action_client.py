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

Use this class for every action client.
"""

from __future__ import annotations

import time
from typing import Any

from rclpy.action import ActionClient as _RclpyActionClient
from rclpy.task import Future

__all__ = ["ActionClient", "LATE_FEEDBACK_GRACE"]

# s a goal's feedback callback outlives its result: a starved client (one message per wake-up) can still be taking
# that goal's queued feedback many seconds after the result is in (a stress run's route test never saw its arrival
# feedback with 5 s here; the last one it had taken was an early one)
LATE_FEEDBACK_GRACE = 30.0


class ActionClient(_RclpyActionClient):
    """rclpy.action.ActionClient whose send_goal_async returns the future the goal response completes, and whose
    feedback callbacks outlive their goal's result by LATE_FEEDBACK_GRACE seconds."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._feedback_expiry: dict[bytes, float] = {}  # finished goal's uuid -> when its callback goes

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
