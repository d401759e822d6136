"""What a service call that got no answer says about the server (tb4.navigator._services.ServiceCaller), down to a
node that is being destroyed while the text is built: the timeout is raised all the same. Over DDS the text is
checked in tests/ros/test_navigator_robustness.py; here its parts, on stand-ins, without a node."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

pytest.importorskip("rclpy", reason="ROS wheels not installed")

from tb4.navigator._services import ServiceCaller  # noqa: E402

pytestmark = pytest.mark.core


def test_the_server_state_counts_requests_and_survives_a_node_going_away() -> None:
    caller = SimpleNamespace(_graph_report=lambda name: f"1 request reader of {name}")
    ready = SimpleNamespace(service_is_ready=lambda: True)
    said = ServiceCaller._server_state(caller, ready, "amcl/get_state", 1)  # type: ignore[arg-type]
    assert said == "1 request unanswered; the server is ready: yes; the graph shows 1 request reader of amcl/get_state"

    def destroyed() -> bool:
        raise RuntimeError("cannot use Destroyable because destruction was requested")

    gone = SimpleNamespace(service_is_ready=destroyed)
    said = ServiceCaller._server_state(caller, gone, "amcl/get_state", 3)  # type: ignore[arg-type]
    assert said == (
        "3 requests unanswered; the server's state unknown "
        "(RuntimeError: cannot use Destroyable because destruction was requested)"
    )
