"""A raw-rclpy test client: its own context and a spinning executor thread, every wait bounded."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from typing import Any

from rclpy.qos import QoSProfile

from tb4.core.waits import WaitTimeout, wait_for_future
from tb4.ros.action_client import ActionClient
from tb4.ros.background import BackgroundNode
from tb4.ros.qos import REQUESTS


class RosClient:
    """Spun by tb4's one background spinner (a SingleThreadedExecutor: rclpy's MultiThreadedExecutor could not
    keep up with a 10x simulator's topics, and deep queues fell seconds behind); action clients are built with
    the spinner paused, as rclpy registers one with the node before it is complete."""

    def __init__(self, name: str = "test_client", namespace: str = "") -> None:
        self._background = BackgroundNode(name, namespace)
        self.context = self._background.context
        self.node = self._background.node
        self._background.start()
        self._clients: dict[tuple[Any, str], Any] = {}

    def close(self) -> None:
        self._background.close()

    def paused(self) -> contextlib.AbstractContextManager[None]:
        """Keep the spin thread out of the node: nothing is taken meanwhile (a script's busy executor)."""
        return self._background.paused()

    # --- topics ------------------------------------------------------------------------------------------------
    def latest(self, msg_type: Any, topic: str, qos: QoSProfile | int = 10) -> Callable[[], Any]:
        """Subscribe and return a getter for the newest message (None until one arrives)."""
        box: dict[str, Any] = {"msg": None}
        subscription = self.node.create_subscription(msg_type, topic, lambda m: box.__setitem__("msg", m), qos)

        def newest() -> Any:
            return box["msg"]

        newest.subscription = subscription  # type: ignore[attr-defined]  # wait_for reports its matched writers
        return newest

    def every(self, msg_type: Any, topic: str, depth: int = 2000) -> Callable[[], list]:
        """Subscribe and return a getter of every message received so far, oldest first.

        For a state that passes faster than a loaded test process may sleep: a 10x simulator's 6 s turn lasts
        0.6 s of wall time, and a test that polls the newest message (`latest`) can wake after it. The reader's
        queue is deep so that the messages of a whole turn wait for the spin thread while the process sleeps.
        """
        received: list = []
        subscription = self.node.create_subscription(msg_type, topic, received.append, QoSProfile(depth=depth))

        def so_far() -> list:
            return received

        so_far.subscription = subscription  # type: ignore[attr-defined]  # wait_for reports its matched writers
        return so_far

    def first(
        self, received: Callable[[], list], predicate: Callable[[Any], bool], timeout: float = 20.0, what: str = ""
    ) -> Any:
        """The first message of `received` (a getter from `every`) that `predicate` accepts, waiting up to `timeout`
        s for one. Each message is looked at once, however long the list grows."""
        checked = 0

        def found() -> Any:
            nonlocal checked
            seen = received()
            end = len(seen)  # the spin thread appends meanwhile: look at what is there now
            for message in seen[checked:end]:
                if predicate(message):
                    return message
            checked = end
            return None

        found.subscription = getattr(received, "subscription", None)  # type: ignore[attr-defined]
        try:
            return self.wait_for(found, timeout=timeout, what=what)
        except WaitTimeout as exc:
            seen = received()
            newest = f"; the newest: {seen[-1]!r:.300}" if seen else ""
            raise WaitTimeout(f"{exc}; {len(seen)} messages received{newest}") from None

    def wait_for(
        self,
        getter: Callable[[], Any],
        predicate: Callable[[Any], bool] = lambda m: m is not None,
        timeout: float = 20.0,
        what: str = "a message",
    ) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = getter()
            if value is not None and predicate(value):
                return value
            time.sleep(0.01)
        subscription = getattr(getter, "subscription", None)
        matched = "" if subscription is None else f"; writers matched: {subscription.get_publisher_count()}"
        raise WaitTimeout(f"timed out after {timeout} s waiting for {what} (last: {getter()!r:.300}{matched})")

    def publish_until(
        self,
        msg_type: Any,
        topic: str,
        msg: Any,
        getter: Callable[[], Any],
        what: str,
        predicate: Callable[[Any], bool] = lambda m: m is not None,
        timeout: float = 30.0,
    ) -> Any:
        """Publish `msg` on `topic` every 0.1 s until `getter()` has a value that `predicate` accepts, and return
        it: a volatile topic's message is lost until the subscriber is matched, which a loaded machine may take
        seconds to do (the tests once published for 10 s, then only waited)."""
        publisher = self.node.create_publisher(msg_type, topic, 10)
        next_publish = 0.0

        def publishing() -> Any:
            nonlocal next_publish
            if time.monotonic() >= next_publish:
                publisher.publish(msg)
                next_publish = time.monotonic() + 0.1
            return getter()

        publishing.subscription = getattr(getter, "subscription", None)  # type: ignore[attr-defined]
        try:
            return self.wait_for(publishing, predicate, timeout, what)
        except WaitTimeout as exc:
            raise WaitTimeout(f"{exc}, publishing on {topic} ({publisher.get_subscription_count()} readers)") from None

    # --- actions and services ----------------------------------------------------------------------------------
    def action(
        self, action_type: Any, name: str, goal: Any, timeout: float = 60.0, feedback: list | None = None
    ) -> tuple[int, Any]:
        """Send a goal; returns (status, result). status is GoalStatus (4 succeeded, 5 canceled, 6 aborted),
        or -1 when the goal was rejected."""
        handle = self.send_goal(action_type, name, goal, feedback)
        if not handle.accepted:
            return -1, None
        response = wait_for_future(handle.get_result_async(), timeout, f"result of {name}")
        return response.status, response.result

    def action_client(self, action_type: Any, name: str) -> ActionClient:
        """The client of this action, created on first use. Create it ahead of the first goal where discovery may
        be slow: the server must also match the client's readers (only the client's side is seen by
        wait_for_server), and a goal response sent before that reaches nobody."""
        key = (action_type, name)
        if key not in self._clients:
            with self._background.paused():  # a deep feedback queue: a starved test thread must not lose feedback
                self._clients[key] = ActionClient(
                    self.node, action_type, name, feedback_sub_qos_profile=QoSProfile(depth=1000)
                )
        return self._clients[key]

    def send_goal(self, action_type: Any, name: str, goal: Any, feedback: list | None = None) -> Any:
        client = self.action_client(action_type, name)
        if not client.wait_for_server(timeout_sec=20.0):
            raise WaitTimeout(f"no action server '{name}' after 20 s")
        callback = (lambda m: feedback.append(m.feedback)) if feedback is not None else None
        return wait_for_future(client.send_goal_async(goal, feedback_callback=callback), 10.0, f"{name} acceptance")

    def settled(
        self, feedback: list, predicate: Callable[[list], bool], what: str, timeout: float = 25.0, limit: float = 180.0
    ) -> list:
        """The feedback received so far, once it satisfies `predicate`. Feedback and the result travel apart, and
        rclpy takes one feedback message per wake-up, so a goal's result can be in before its last feedback. A
        starved client can be far behind a server that sends large feedback every cycle (route tracking: the whole
        route and path, 20 per wall second, as Nav2 sends it every cycle): while feedback still comes in, the wait
        goes on (up to `limit` s in all); it fails `timeout` s after the last one came."""
        start = time.monotonic()
        count, quiet_since = -1, start
        while True:
            now = time.monotonic()
            received = list(feedback)
            if received and predicate(received):
                return received
            if len(received) != count:
                count, quiet_since = len(received), now
            if now - quiet_since > timeout or now - start > limit:
                last = received[-1] if received else None
                raise WaitTimeout(
                    f"timed out waiting for {what}: {len(received)} feedback messages in {now - start:.1f} s, none for "
                    f"the last {now - quiet_since:.1f} s (last: {last!r:.300})"
                )
            time.sleep(0.01)

    def service_client(self, srv_type: Any, name: str) -> Any:
        """The one client of this service (made once, then kept), its server discovered. A test that must call at
        a given moment asks for it beforehand: discovering a new client's endpoints can take seconds when the
        machine is loaded."""
        key = (srv_type, name)
        if key not in self._clients:
            with self._background.paused():
                self._clients[key] = self.node.create_client(srv_type, name, qos_profile=REQUESTS)
        client = self._clients[key]
        if not client.wait_for_service(timeout_sec=20.0):
            raise WaitTimeout(f"no service '{name}' after 20 s")
        return client

    def service(self, srv_type: Any, name: str, request: Any, timeout: float = 10.0) -> Any:
        client = self.service_client(srv_type, name)
        return wait_for_future(client.call_async(request), timeout, f"response of {name}")


def navigate_to_pose_goal(x: float, y: float, yaw: float = 0.0) -> Any:
    """A NavigateToPose goal at (x, y, yaw) in the map frame, as a raw client builds one."""
    from geometry_msgs.msg import PoseStamped
    from nav2_msgs.action import NavigateToPose

    from tb4.ros.convert import yaw_to_quaternion

    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = x, y
    msg.pose.orientation = yaw_to_quaternion(yaw)
    return NavigateToPose.Goal(pose=msg)
