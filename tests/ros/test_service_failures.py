"""A service callback of ours that raises is answered with a failure where its response can say one
(tb4.ros.replies.failure_response), over DDS with rclpy's own client: rclpy sends no reply at all for such a
request, and the caller waited for its whole time limit without a word."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from nav2_msgs.srv import LoadMap
from std_srvs.srv import Empty, Trigger

from tb4.core.waits import wait_until
from tb4.ros.background import BackgroundNode
from tb4.ros.replies import create_service, failure_response

ANSWER_LIMIT = 10.0  # s for an answer that must come
ASK_AGAIN = 0.5  # s without an answer before the request is asked again


def _broken(_request: Any, _response: Any) -> Any:
    raise ValueError("the map file is not a map")


@pytest.fixture
def sides() -> Iterator[tuple[BackgroundNode, BackgroundNode]]:
    server_side = BackgroundNode("failing_services")
    client_side = BackgroundNode("failing_services_client")
    for srv_type, name in ((Trigger, "broken_trigger"), (LoadMap, "broken_load_map"), (Empty, "broken_empty")):
        create_service(server_side.node, srv_type, name, _broken)
    server_side.start()
    client_side.start()
    try:
        yield server_side, client_side
    finally:
        client_side.close()
        server_side.close()


def _call(client_side: BackgroundNode, srv_type: Any, name: str, patience: float) -> Any:
    """The reply, or None. The request is asked again every half second: in one process, a request sent the moment
    the client has matched the server can be lost (the server's reader has not matched it yet)."""
    with client_side.paused():
        client = client_side.node.create_client(srv_type, name)
    assert client.wait_for_service(timeout_sec=20.0), f"no service '{name}' after 20 s"
    futures: list[Any] = []
    for _ in range(round(patience / ASK_AGAIN)):
        futures.append(client.call_async(srv_type.Request()))
        if wait_until(lambda: any(f.done() for f in futures), ASK_AGAIN):
            return next(f for f in futures if f.done()).result()
    return None


def test_a_trigger_whose_callback_raises_answers_failed_with_the_reason(sides) -> None:
    _server_side, client_side = sides
    reply = _call(client_side, Trigger, "broken_trigger", ANSWER_LIMIT)
    assert reply is not None, "no reply"
    assert reply.success is False
    assert "ValueError: the map file is not a map" in reply.message


def test_a_load_map_whose_callback_raises_answers_its_undefined_failure(sides) -> None:
    _server_side, client_side = sides
    reply = _call(client_side, LoadMap, "broken_load_map", ANSWER_LIMIT)
    assert reply is not None, "no reply"
    assert reply.result == LoadMap.Response.RESULT_UNDEFINED_FAILURE


def test_a_response_that_cannot_say_failure_gets_none() -> None:
    # an empty reply would read as success: the caller's own bound reports the failure
    assert failure_response(Empty, "x") is None
    assert failure_response(Trigger, "why").message == "why"
