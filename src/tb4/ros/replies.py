"""Service and action replies (and action feedback) that reach a client created a moment ago.

A DDS client is a request writer and a reply reader, announced separately. A server can receive the request of a
brand-new client before it has discovered that client's reply reader; rmw_fastrtps then waits only the reply
writer's max_blocking_time (100 ms) and drops the reply ("failed to send response (timeout): client will not
receive response"), so the client waits for an answer that never comes. On a loaded machine discovery takes longer
than that. Every server of ours therefore holds a reply, bounded, until each participant that writes requests also
has its reply readers discovered; then it sends. Nothing changes for a client whose reader is already known.

A service callback that raises is answered too, with a failure where the response type can say one
(failure_response): rclpy itself sends nothing then.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.service import Service

from tb4.core.waits import wait_until
from tb4.ros.qos import REQUESTS, serves

__all__ = [
    "REPLY_READER_WAIT",
    "counted",
    "create_service",
    "dds_topic",
    "failure_response",
    "feedback_readers_known",
    "reply_readers_known",
    "reply_topic",
    "request_topic",
    "service_graph_report",
    "wait_for_action_reply_readers",
    "wait_for_feedback_readers",
    "wait_for_reply_readers",
]

REPLY_READER_WAIT = 2.0  # s a reply may wait for its client's reply reader; then it is sent anyway
_POLL = 0.005  # s between two looks at the graph while holding a reply


def request_topic(service_name: str) -> str:
    """The DDS topic of `service_name`'s requests (fully qualified), as the graph names it (query with no_mangle)."""
    return f"rq{service_name}Request"


def reply_topic(service_name: str) -> str:
    """The DDS topic of `service_name`'s replies (fully qualified), as the graph names it (query with no_mangle)."""
    return f"rr{service_name}Reply"


def dds_topic(topic_name: str) -> str:
    """The DDS topic of ROS topic `topic_name` (fully qualified), as the graph names it (query with no_mangle)."""
    return f"rt{topic_name}"


def counted(count: int, noun: str) -> str:
    """`count` and `noun`, plural unless one ("1 reply writer", "0 reply writers")."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def service_graph_report(node: Node, service_name: str, *, clients: bool = False) -> str:
    """What `node`'s view of the graph shows of `service_name`'s servers (fully qualified), for an error that says
    why a server is not ready or did not answer: their request readers and reply writers (rmw_fastrtps calls a
    server available only when the two counts are equal and the client has matched both). With `clients`: the
    clients' request writers and reply readers instead, for a server's message.

    Returns:
        e.g. "1 request reader, 1 reply writer" ("1 request writer, 0 reply readers" with `clients`).
    """
    if clients:
        requests_by, replies_by = node.get_publishers_info_by_topic, node.get_subscriptions_info_by_topic
        nouns = ("request writer", "reply reader")
    else:
        requests_by, replies_by = node.get_subscriptions_info_by_topic, node.get_publishers_info_by_topic
        nouns = ("request reader", "reply writer")
    requests = len(requests_by(request_topic(service_name), no_mangle=True))
    replies = len(replies_by(reply_topic(service_name), no_mangle=True))
    return f"{counted(requests, nouns[0])}, {counted(replies, nouns[1])}"


def _participants(infos: list[Any]) -> Counter[bytes]:
    """How many endpoints each participant has among `infos` (a DDS GUID starts with its participant's prefix)."""
    return Counter(bytes(info.endpoint_gid[:12]) for info in infos)


def reply_readers_known(node: Node, service_name: str) -> bool:
    """True when every participant writing requests to `service_name` (fully qualified) has as many reply
    readers as request writers in this node's view of the graph."""
    writers = _participants(node.get_publishers_info_by_topic(request_topic(service_name), no_mangle=True))
    if not writers:
        return True
    readers = _participants(node.get_subscriptions_info_by_topic(reply_topic(service_name), no_mangle=True))
    return all(readers[participant] >= count for participant, count in writers.items())


def wait_for_reply_readers(node: Node, service_name: str, timeout: float = REPLY_READER_WAIT) -> bool:
    """Wait (at most `timeout` s) until reply_readers_known; False if it never became true, which is logged: the
    client can only say it got no answer, and this line tells which side lost it."""
    if wait_until(lambda: reply_readers_known(node, service_name), timeout, period=_POLL):
        return True
    seen = service_graph_report(node, service_name, clients=True)
    node.get_logger().warning(
        f"service '{service_name}': a client's reply reader was not in the graph after {timeout:g} s (the graph "
        f"shows {seen}); the reply is sent all the same and may be lost"
    )
    return False


def wait_for_action_reply_readers(
    node: Node, action_name: str, service: str, timeout: float = REPLY_READER_WAIT
) -> bool:
    """wait_for_reply_readers for a service of action `action_name` (fully qualified): "send_goal" before the goal
    response goes out (rclpy sends it right after the goal callback), "get_result" before the result (right after
    the execute callback)."""
    return wait_for_reply_readers(node, f"{action_name}/_action/{service}", timeout)


def feedback_readers_known(node: Node, action_name: str, feedback_writer: Publisher | None = None) -> bool:
    """True when every participant writing goal requests to `action_name` (fully qualified) has a feedback reader
    and a status reader in this node's view of the graph (every rcl action client has both), and `feedback_writer`,
    if given, has matched every feedback reader it can serve there.

    The graph alone is not enough: Fast DDS tells the graph of a new remote reader before it pairs this process's
    writers with it, one writer after another, and a message a writer sends before its pairing never reaches that
    reader. rcl_action's own feedback writer has no matched count to read; the writer whose feedback goes out
    (tb4.ros.action_bridge) has.
    """
    writers = _participants(node.get_publishers_info_by_topic(request_topic(f"{action_name}/_action/send_goal"), True))
    if not writers:
        return True
    feedback_infos = node.get_subscriptions_info_by_topic(dds_topic(f"{action_name}/_action/feedback"), True)
    feedback = _participants(feedback_infos)
    status = _participants(node.get_subscriptions_info_by_topic(dds_topic(f"{action_name}/_action/status"), True))
    if not all(feedback[participant] and status[participant] for participant in writers):
        return False
    if feedback_writer is None:
        return True
    servable = sum(serves(feedback_writer.qos_profile, info.qos_profile) for info in feedback_infos)
    return feedback_writer.get_subscription_count() >= servable


def wait_for_feedback_readers(
    node: Node, action_name: str, feedback_writer: Publisher | None = None, timeout: float = REPLY_READER_WAIT
) -> bool:
    """Wait (at most `timeout` s) until feedback_readers_known. Feedback is volatile: a goal of a brand-new client
    that runs before the server has matched the client's feedback reader sends that client nothing, and at --rate
    max a whole goal can end within that time (seen under load: a drive with no feedback at all, and a goal whose
    first feedback never came)."""
    return wait_until(lambda: feedback_readers_known(node, action_name, feedback_writer), timeout, period=_POLL)


def failure_response(srv_type: Any, message: str) -> Any | None:
    """A response of `srv_type` that says the request failed, or None if the type has no way to say so.

    A response says failure with a `success` flag (Trigger, ManageLifecycleNodes, the Create 3's EStop and
    RobotPower), or a `result` code whose type names RESULT_UNDEFINED_FAILURE (LoadMap); `message` or `error_msg`,
    if there, carry `message`. Any other response (Empty, GetCostmap) would read as success, so there is none.
    """
    response = srv_type.Response()
    fields = response.get_fields_and_field_types()
    if fields.get("success") == "boolean":
        response.success = False
    elif "result" in fields and hasattr(srv_type.Response, "RESULT_UNDEFINED_FAILURE"):
        response.result = srv_type.Response.RESULT_UNDEFINED_FAILURE
    else:
        return None
    for text in ("message", "error_msg"):
        if fields.get(text) == "string":
            setattr(response, text, message)
    return response


def _answering_failures(node: Node, srv_type: Any, name: str, callback: Callable[[Any, Any], Any]) -> Callable:
    """`callback`, whose exception is answered with failure_response: rclpy sends no reply at all for a request
    whose callback raised, and its client waited for its whole time limit without a word."""

    def guarded(request: Any, response: Any) -> Any:
        try:
            return callback(request, response)
        except Exception as exc:
            reason = f"{type(exc).__name__}: {exc}"
            failed = failure_response(srv_type, f"{name} failed ({reason})")
            answered = "answered as failed" if failed is not None else "no reply: its response cannot say failure"
            node.get_logger().error(f"service '{name}': the request failed ({reason}); {answered}")
            if failed is None:
                raise
            return failed

    return guarded


def create_service(node: Node, srv_type: Any, name: str, callback: Callable[[Any, Any], Any], **kwargs: Any) -> Service:
    """node.create_service, with replies held until the caller's reply reader is discovered (see above), a deep
    request queue (tb4.ros.qos.REQUESTS) unless `qos_profile` says otherwise, and a callback that raises answered
    with a failure where the response can say one (failure_response)."""
    kwargs.setdefault("qos_profile", REQUESTS)
    service = node.create_service(srv_type, name, _answering_failures(node, srv_type, name, callback), **kwargs)
    send = service.send_response
    full_name = node.resolve_service_name(service.srv_name)

    def send_when_readable(response: Any, header: Any) -> None:
        wait_for_reply_readers(node, full_name)
        send(response, header)

    service.send_response = send_when_readable  # type: ignore[method-assign]  # the executor calls this one
    return service
