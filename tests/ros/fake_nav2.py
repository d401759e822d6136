"""Small Nav2 servers written in raw rclpy, as Nav2 would serve them, for navigator methods the simulator does not
serve (routes, GPS waypoints) or behaviours it cannot be made to show on demand (a slow or silent service).

Each server records the goals/requests it received and follows a script given per goal: publish these feedback
messages, then succeed / abort with an error code / wait to be canceled; or reject the goal. Every wait is bounded.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import rclpy
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor

_HOLD_LIMIT = 30.0  # a goal told to wait for its cancel aborts after this many seconds anyway


@dataclass
class Script:
    """What a server does with the next goal."""

    accept: bool = True
    feedback: list[Any] = field(default_factory=list)
    feedback_period: float = 0.05
    outcome: str = "succeed"  # succeed | abort | hold (until canceled)
    result: Any = None
    accept_delay: float = 0.0  # seconds the goal response is held back
    respond: Callable[[Any], tuple[list[Any], Any]] | None = None  # goal -> (feedback, result), computed per goal


class FakeActionServer:
    def __init__(self, owner: FakeNav2, action_type: Any, name: str) -> None:
        self.type = action_type
        self.goals: list[Any] = []
        self.scripts: list[Script] = []
        #: what goals get once the scripts are used up: this server's own (a test that changes it changes no other)
        self.default = Script()
        self.canceled = threading.Event()
        self._owner = owner
        self._count_lock = threading.Lock()
        self._accepted = 0  # goals accepted, whose execute callback rclpy has scheduled
        self._executed = 0  # ... and that have run it to its end
        self._deciding = 0  # goal callbacks in progress
        self._server = ActionServer(
            owner.node,
            action_type,
            name,
            execute_callback=self._execute,
            goal_callback=self._goal,
            cancel_callback=lambda _h: CancelResponse.ACCEPT,
            callback_group=owner.group,
        )

    def _script(self) -> Script:
        return self.scripts[0] if self.scripts else self.default

    def _goal(self, request: Any) -> GoalResponse:
        with self._count_lock:
            self._deciding += 1
        try:
            self.goals.append(request)
            script = self._script()
            held_until = time.monotonic() + script.accept_delay
            while time.monotonic() < held_until and not self._owner.closing:
                time.sleep(0.02)
            if self._owner.closing:  # closing down: no execute callback to schedule
                return GoalResponse.REJECT
            if not script.accept and self.scripts:
                self.scripts.pop(0)
            if script.accept:
                with self._count_lock:
                    self._accepted += 1
            return GoalResponse.ACCEPT if script.accept else GoalResponse.REJECT
        finally:
            with self._count_lock:
                self._deciding -= 1

    def idle(self) -> bool:
        """No goal is being decided on, and every accepted goal has run its execute callback to the end."""
        with self._count_lock:
            return self._deciding == 0 and self._executed >= self._accepted

    def _execute(self, handle: Any) -> Any:
        try:
            return self._run_script(handle)
        finally:
            with self._count_lock:
                self._executed += 1

    def _run_script(self, handle: Any) -> Any:
        script = self.scripts.pop(0) if self.scripts else Script(**vars(self.default))
        if script.respond is not None:
            script.feedback, script.result = script.respond(handle.request)
        for msg in script.feedback:
            handle.publish_feedback(msg)
            time.sleep(script.feedback_period)
        result = script.result if script.result is not None else self.type.Result()
        if script.outcome == "hold":
            deadline = time.monotonic() + _HOLD_LIMIT
            while not handle.is_cancel_requested and not self._owner.closing and time.monotonic() < deadline:
                time.sleep(0.02)
            if handle.is_cancel_requested:
                self.canceled.set()
                handle.canceled()
                return result
            handle.abort()
            return result
        if script.outcome == "abort":
            handle.abort()
        else:
            handle.succeed()
        return result


class FakeService:
    """A service whose n-th request is answered after delays[n] seconds (the last delay repeats)."""

    def __init__(self, owner: FakeNav2, srv_type: Any, name: str, respond: Callable[[Any], Any]) -> None:
        self.requests: list[Any] = []
        self.delays: list[float] = [0.0]
        self._respond = respond
        self._lock = threading.Lock()
        self._answering = 0  # requests taken and not answered yet
        self.handle = owner.node.create_service(srv_type, name, self._handle, callback_group=owner.group)

    def idle(self) -> bool:
        """No request is waiting out its delay (close() lets them answer: rclpy 7 otherwise prints the error of a
        reply sent through a destroyed service when the interpreter ends)."""
        return self._answering == 0

    def _handle(self, request: Any, response: Any) -> Any:
        with self._lock:
            index = len(self.requests)
            self.requests.append(request)
            self._answering += 1
        try:
            time.sleep(self.delays[min(index, len(self.delays) - 1)])
            return self._respond(request) or response
        finally:
            with self._lock:
                self._answering -= 1


class FakeNav2:
    """A node with its own context and executor thread, hosting fake servers."""

    def __init__(self, name: str = "fake_nav2") -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(name, context=self.context)
        self.group = ReentrantCallbackGroup()
        self.executor = MultiThreadedExecutor(num_threads=6, context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self._closing = threading.Event()
        self._servers: list[FakeActionServer] = []
        self._services: list[FakeService] = []
        self._entities: list[Callable[[], Any]] = []  # destroyers of the servers, run by close()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def action(self, action_type: Any, name: str) -> FakeActionServer:
        """A fake action server, returned once it knows the client that will call it (the navigator's, built
        before): rmw_fastrtps waits only 100 ms for a server's reply writer to match the client's reply reader,
        so a goal sent the moment the client sees a brand-new server loses its response on a loaded machine
        ("failed to send response (timeout): client will not receive response")."""
        server = FakeActionServer(self, action_type, name)
        self._servers.append(server)
        self._entities.append(server._server.destroy)
        for service in ("send_goal", "get_result", "cancel_goal"):
            self._wait_for_reply_reader(f"rr/{name}/_action/{service}Reply")
        return server

    def _wait_for_reply_reader(self, reply_topic: str, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while not self.node.get_subscriptions_info_by_topic(reply_topic, no_mangle=True):
            if time.monotonic() > deadline:
                raise TimeoutError(f"fake server: no client reads '{reply_topic}' after {timeout:g} s")
            time.sleep(0.01)

    def service(self, srv_type: Any, name: str, respond: Callable[[Any], Any] = lambda _r: None) -> FakeService:
        service = FakeService(self, srv_type, name, respond)
        self._services.append(service)
        self._entities.append(lambda: self.node.destroy_service(service.handle))
        return service

    @property
    def closing(self) -> bool:
        return self._closing.is_set()

    def close(self, timeout: float = 5.0) -> None:
        """End held goals, let every accepted goal's execute callback run (one left unscheduled when the executor
        shuts down is a coroutine never awaited: rclpy warns about it at garbage collection) and every delayed
        service request be answered (FakeService.idle), stop spinning, destroy
        the servers and the node (they leave the ROS graph), then shut the context down."""
        self._closing.set()  # held goals see `closing` and end
        deadline = time.monotonic() + timeout
        busy = [*self._servers, *self._services]
        while not all(each.idle() for each in busy) and time.monotonic() < deadline:
            time.sleep(0.02)
        self._stop.set()
        self._thread.join(timeout=5.0)
        self.executor.shutdown(timeout_sec=1.0)
        for destroy in self._entities:  # a node's destruction leaves its action servers alive: end them first
            destroy()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
