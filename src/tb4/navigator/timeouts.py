"""Every wait of the navigator has a limit: the defaults live here, one place, configurable per navigator.

Upstream Nav2 Simple Commander waits forever for servers, goal responses, lifecycle states and poses; a script
started before the simulator (or on the wrong ROS_DOMAIN_ID) then hangs silently. Here each wait ends with a
NavigatorTimeout whose message says what was missing, where, and what to check.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

from tb4.core.waits import WaitTimeout

__all__ = ["NavigatorTimeouts", "NavigatorTimeout", "DEFAULT_TIMEOUTS"]

_HINT = "is the simulator or Nav2 running (same ROS_DOMAIN_ID)?"


class NavigatorTimeout(WaitTimeout):
    """A wait of the navigator ran out; the message names what did not arrive. A WaitTimeout (tb4.core.waits), so
    one `except WaitTimeout` catches every wait of tb4; also a TimeoutError, as scripts catch it."""


@dataclass(frozen=True)
class NavigatorTimeouts:
    """Limits in seconds. Discovery/response limits are wall-clock; navigation limits follow the node's clock.

    server: an action server or service to appear (discovery).
    response: a goal to be accepted/rejected, a service to answer, a cancel to be acknowledged.
    result: a blocking call's result (getPath, smoothPath, dock, undock, lifecycle commands).
    lifecycle: waitUntilNav2Active's wait for a node to report 'active'.
    localization: waitUntilNav2Active's wait for amcl_pose after publishing the initial pose.
    dock_status: getDockedStatus's wait for a dock_status message (the first call includes discovering the robot,
        which took over 5 s on a loaded machine).
    clock_discovery: how long the constructor looks for a /clock publisher (0 disables sim-time detection).
    task_poll: the longest isTaskComplete() waits for a running task before answering False.
    server_lost: how long a running goal's action server may send nothing at all (no feedback, no status, no reply
        to the requests every live server answers at once, sent from the first second of silence on) before the
        goal ends FAILED as lost. A server whose node leaves the ROS graph fails its goal at once; a process killed
        hard stays in the graph for its DDS lease (Fast DDS: 20 s), so this limit is what notices it sooner. A
        healthy simulator answers within a fraction of a second even on a loaded machine.
    """

    server: float = 10.0
    response: float = 10.0
    result: float = 120.0
    lifecycle: float = 60.0
    localization: float = 30.0
    dock_status: float = 20.0
    clock_discovery: float = 1.0
    task_poll: float = 0.1
    server_lost: float = 5.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise TypeError(f"timeout '{f.name}' must be a number of seconds, got {type(value).__name__}")
            zero_ok = f.name == "clock_discovery"
            if not math.isfinite(value) or value < 0 or (value == 0 and not zero_ok):
                raise ValueError(
                    f"timeout '{f.name}' must be a positive, finite number of seconds, got {value!r} "
                    "(waiting forever is what made upstream scripts hang)"
                )

    def with_(self, **changes: Any) -> NavigatorTimeouts:
        """A copy with some limits changed, e.g. `timeouts.with_(server=30)`."""
        return replace(self, **changes)


DEFAULT_TIMEOUTS = NavigatorTimeouts()


def missing_server(kind: str, name: str, namespace: str, seconds: float) -> str:
    ns = namespace or "/"
    return f"no {kind} '{name}' in namespace '{ns}' after {seconds:g} s — {_HINT}"
