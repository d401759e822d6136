"""A goal whose goal response does not come is sent again under a new id (tb4.ros.action_client), and the silent
send cannot run beside or over it: it is canceled by its id, canceled through its handle if accepted late, and
rejected by tb4's own servers when its cancel came first (tb4.ros.action_bridge).

The server here stashes the goal requests of ids the test names, as if DDS had lost or delayed them: a lost
request is never answered, a delayed one is answered when the test releases it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
import rclpy.action
from nav2_msgs.action import ComputePathToPose
from rclpy.action import ActionServer, GoalResponse

import tb4.ros.action_client as action_client_module
from tb4.core.waits import wait_for_future, wait_until
from tb4.ros.action_bridge import _ActionServer
from tb4.ros.action_client import ActionClient
from tb4.ros.background import BackgroundNode
from tb4.ros.qos import REQUESTS

RESEND_AFTER = 0.5  # s: the tests' resend period (the real one waits longer for an answer)
ANSWER_LIMIT = 10.0  # s a test waits for an answer that must come


class StashingServer(ActionServer):
    """rclpy's own action server (the kind most third-party servers are), which stashes the goal requests of the
    ids in `stash` instead of answering them, and records every goal id a cancel named."""

    def __init__(self, node: Any, name: str) -> None:
        self.stash: set[bytes] = set()
        self.stashed: list[Any] = []
        self.cancels: list[bytes] = []
        super().__init__(
            node,
            ComputePathToPose,
            name,
            execute_callback=self._execute,
            goal_callback=lambda _goal: GoalResponse.ACCEPT,
        )

    async def _execute_goal_request(self, request_header_and_message: Any) -> None:
        if bytes(request_header_and_message[1].goal_id.uuid) in self.stash:
            self.stashed.append(request_header_and_message)
            return
        await super()._execute_goal_request(request_header_and_message)

    async def _execute_cancel_request(self, request_header_and_message: Any) -> None:
        self.cancels.append(bytes(request_header_and_message[1].goal_info.goal_id.uuid))
        await super()._execute_cancel_request(request_header_and_message)

    def release(self, executor: Any) -> None:
        """Answer the stashed requests now, as a late delivery would have them answered."""
        for request in self.stashed:
            executor.create_task(ActionServer._execute_goal_request(self, request))
        self.stashed.clear()

    def _execute(self, handle: Any) -> Any:
        handle.succeed()
        return ComputePathToPose.Result()


@pytest.fixture
def sides(monkeypatch: pytest.MonkeyPatch) -> Iterator[tuple[BackgroundNode, StashingServer, BackgroundNode]]:
    monkeypatch.setattr(action_client_module, "GOAL_RESEND_AFTER", RESEND_AFTER)
    server_side = BackgroundNode("resend_server")
    client_side = BackgroundNode("resend_client")
    server = StashingServer(server_side.node, "resend")
    server_side.start()
    client_side.start()
    try:
        yield server_side, server, client_side
    finally:
        client_side.close()
        server_side.close()


def _client(client_side: BackgroundNode, client_class: type = ActionClient, name: str = "resend") -> Any:
    with client_side.paused():
        client = client_class(client_side.node, ComputePathToPose, name)
    assert client.wait_for_server(timeout_sec=20.0), f"no action server '{name}' after 20 s"
    return client


def _cancels_reach_the_server(client: ActionClient) -> None:
    """Probe until one probe is answered: in one process, a request sent the moment the client has matched the
    server can be lost (the server's reader has not matched it yet), and a cancel is not sent again."""
    for _ in range(20):
        probe = client.probe_async()
        if wait_until(probe.done, 0.5):
            return
        client.forget_request(probe)
    raise AssertionError("no probe of 20 was answered by the in-process server")


def _send_with_silent_first(server: StashingServer, client_side: BackgroundNode) -> tuple[Any, Any]:
    """(the first send's goal id, the GoalSend) of a goal whose first send the server stashes."""
    client = _client(client_side)
    first = client.new_goal_id()
    server.stash.add(bytes(first.uuid))
    return first, client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=first)


def _answered_again(server: StashingServer, send: Any, first: Any) -> Any:
    """The handle the goal sent again got, once the server has also had the silent first id's cancel."""
    handle = wait_for_future(send, ANSWER_LIMIT, "the goal response of the goal sent again")
    assert handle.accepted
    assert wait_until(lambda: bytes(first.uuid) in server.cancels, ANSWER_LIMIT), "the silent id was not canceled"
    return handle


def test_a_lost_goal_request_is_sent_again_and_the_silent_id_canceled(sides) -> None:
    _server_side, server, client_side = sides
    first, send = _send_with_silent_first(server, client_side)
    handle = _answered_again(server, send, first)
    assert send.goal_ids[0] is first and len(send.goal_ids) >= 2
    assert bytes(handle.goal_id.uuid) == bytes(send.goal_ids[-1].uuid) != bytes(first.uuid)


class _SaidWarnings:
    """A client's logger that also keeps what it warned (rclpy's logger writes from C, out of pytest's reach)."""

    def __init__(self, logger: Any) -> None:
        self._logger = logger
        self.warnings: list[str] = []

    def warning(self, message: str) -> None:
        self.warnings.append(message)
        self._logger.warning(message)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._logger, name)


def test_the_resend_warning_says_whether_the_server_is_ready_and_what_the_graph_shows(sides) -> None:
    _server_side, server, client_side = sides
    client = _client(client_side)
    said = _SaidWarnings(client._logger)
    client._logger = said
    first = client.new_goal_id()
    server.stash.add(bytes(first.uuid))
    _answered_again(server, client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=first), first)
    resends = [text for text in said.warnings if text.startswith("no goal response from 'resend'")]
    assert resends, said.warnings
    assert "the server is ready: yes; the graph shows send_goal: 1 request reader, 1 reply writer" in resends[0]


def test_rclpys_own_client_waits_forever_for_that_lost_request(sides) -> None:
    _server_side, server, client_side = sides
    client = _client(client_side, rclpy.action.ActionClient)
    first = client._generate_random_uuid()
    server.stash.add(bytes(first.uuid))
    future = client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=first)
    assert not wait_until(future.done, 4 * RESEND_AFTER), "the stashing server answered a stashed request"


def test_a_send_answered_late_is_canceled_and_the_latest_send_runs(sides) -> None:
    server_side, server, client_side = sides
    first, send = _send_with_silent_first(server, client_side)
    handle = _answered_again(server, send, first)
    server.release(server_side.node.executor)  # the silent send arrives after all, and is accepted (rclpy's server)
    assert wait_until(lambda: server.cancels.count(bytes(first.uuid)) == 2, ANSWER_LIMIT), (
        "the send accepted late was not canceled through its handle"
    )
    assert bytes(handle.goal_id.uuid) not in server.cancels
    result = wait_for_future(handle.get_result_async(), ANSWER_LIMIT, "the latest send's result")
    assert result.status == 4  # SUCCEEDED: the goal sent again ran to its end


def test_a_send_stopped_by_its_caller_goes_no_more(sides) -> None:
    _server_side, server, client_side = sides
    _first, send = _send_with_silent_first(server, client_side)
    send.stop_resending()
    assert not wait_until(lambda: len(send.goal_ids) > 1, 4 * RESEND_AFTER)
    assert not send.done()


def _our_server_and_client(server_side: BackgroundNode, client_side: BackgroundNode) -> tuple[Any, Any, list]:
    """(tb4's action server, a client whose goals and cancels reach it, the goals it has decided on since)."""
    decided: list[Any] = []
    with server_side.paused():
        server = _ActionServer(
            server_side.node,
            ComputePathToPose,
            "overtaken",
            execute_callback=lambda handle: (handle.succeed(), ComputePathToPose.Result())[1],
            goal_callback=lambda goal: (decided.append(goal), GoalResponse.ACCEPT)[1],
            on_cancels_marked=lambda: None,
            goal_service_qos_profile=REQUESTS,  # as every server of the simulator (TaskActionServer)
            cancel_service_qos_profile=REQUESTS,
            result_service_qos_profile=REQUESTS,
        )
    client = _client(client_side, name="overtaken")
    warm = wait_for_future(client.send_goal_async(ComputePathToPose.Goal()), ANSWER_LIMIT, "a first goal's answer")
    assert warm.accepted  # goal requests reach the server from now on (see _cancels_reach_the_server)
    _cancels_reach_the_server(client)
    decided.clear()
    return server, client, decided


def test_our_server_rejects_a_goal_whose_cancel_came_first(sides) -> None:
    server_side, _server, client_side = sides
    _ours, client, decided = _our_server_and_client(server_side, client_side)
    overtaken = client.new_goal_id()
    answer = wait_for_future(client.cancel_goal_id_async(overtaken), ANSWER_LIMIT, "the cancel's answer")
    assert not answer.goals_canceling  # unknown to the server, as the goal had not come yet
    late_send = client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=overtaken)
    late = wait_for_future(late_send, ANSWER_LIMIT, "the late goal's answer")
    assert not late.accepted and not decided, "a goal whose cancel came first was decided on"
    fresh = wait_for_future(client.send_goal_async(ComputePathToPose.Goal()), ANSWER_LIMIT, "a fresh goal's answer")
    assert fresh.accepted and len(decided) == 1
    assert len(late_send.goal_ids) == 1  # answered by the first send: the rejection is the server's


def test_an_answer_taken_while_the_resend_is_being_armed_stops_it(monkeypatch: pytest.MonkeyPatch) -> None:
    """The executor's thread can take the goal response while the sending thread is still arming the resend (a
    stress run: the timer was gone before it was started, and send_goal_async raised AttributeError)."""
    from tb4.ros.action_client import GoalSend

    send = GoalSend(ComputePathToPose.Goal(), None)
    fired: list[bool] = []
    real_timer = action_client_module.threading.Timer

    def timer_answered_meanwhile(after: float, function: Any) -> Any:
        with send.lock:  # what _on_goal_answer does for the latest send, from another thread
            send.stopped = True
        send.disarm()
        return real_timer(after, function)

    monkeypatch.setattr(action_client_module.threading, "Timer", timer_answered_meanwhile)
    send.arm(0.05, lambda: fired.append(True))
    assert not wait_until(lambda: fired, 0.5), "a goal already answered was sent again"


def test_a_flood_of_cancels_for_unknown_ids_keeps_our_server_bounded(sides, monkeypatch: pytest.MonkeyPatch) -> None:
    """A client that cancels random ids without end (hostile, or a liveness probe left running) leaves at most
    CANCELED_UNSEEN_LIMIT of them remembered, the latest, and the server goes on deciding goals."""
    import tb4.ros.action_bridge as action_bridge

    monkeypatch.setattr(action_bridge, "CANCELED_UNSEEN_LIMIT", 50)
    server_side, _server, client_side = sides
    ours, client, decided = _our_server_and_client(server_side, client_side)
    ids = [client.new_goal_id() for _ in range(300)]
    answers = [client.cancel_goal_id_async(goal_id) for goal_id in ids]
    assert wait_until(lambda: all(a.done() for a in answers), 60.0), "not every cancel of the flood was answered"
    assert len(ours._canceled_unseen) == 50
    assert bytes(ids[-1].uuid) in ours._canceled_unseen and bytes(ids[0].uuid) not in ours._canceled_unseen
    late = wait_for_future(
        client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=ids[-1]), ANSWER_LIMIT, "the latest id's answer"
    )
    assert not late.accepted and not decided  # the latest is still refused
    old = wait_for_future(
        client.send_goal_async(ComputePathToPose.Goal(), goal_uuid=ids[0]), ANSWER_LIMIT, "the oldest id's answer"
    )
    assert old.accepted and len(decided) == 1  # the oldest made room: decided as any goal
