"""Whether a running goal's action server is still there: the navigator fails a goal whose server went away.

A goal whose server died gets no result, so without this a script polling isTaskComplete() (and startToPose,
dock, ...) waits forever. Two signs, either enough:

- the graph: the server's endpoints left the ROS graph (`server_is_ready()` turned False on two looks in a row).
  Immediate when the server's process ends cleanly; a process killed hard stays in the graph until its DDS lease
  runs out (Fast DDS's default: 20 s).
- silence: nothing from the server (no feedback, no status, no reply) for `limit` seconds although it was asked
  something every live action server answers at once (ActionClient.probe_async), first after PROBE_AFTER s of
  silence and then every PROBE_PERIOD s. A healthy server that legitimately says nothing for a while (a Wait
  behaviour, a robot charging on its dock, a simulator pausing between ticks) still answers the probe, so only a
  server that stopped answering altogether is taken for gone.

The checks are cheap and rate-limited (one look at the graph per GRAPH_PERIOD), so every wait of the navigator
runs them on each turn.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

from tb4.ros.action_client import ActionClient

__all__ = ["ServerWatch", "GRAPH_PERIOD", "GRAPH_QUIET", "PROBE_AFTER", "PROBE_PERIOD", "CONFIRM"]

GRAPH_PERIOD = 0.25  # wall s between two looks at the graph
GRAPH_QUIET = 1.5  # wall s of silence (a probe unanswered: PROBE_AFTER) before absence from the graph counts
# wall s of silence before the first probe: a running goal of the simulator sends feedback every
# tb4.ros.action_bridge.FEEDBACK_PERIOD (0.05 s), and Nav2's servers send theirs as often
PROBE_AFTER = 1.0
PROBE_PERIOD = 1.0  # wall s between probes while the silence lasts
# wall s the verdict "silent" waits once reached, so that answers that came in while this process itself stood still
# (stopped, starved) are taken first: the spin thread needs a moment to take them
CONFIRM = 0.3


class ServerWatch:
    """Watches the action server of one goal (see the module docstring); `check()` says why it is gone, if it is.

    Args:
        client: the goal's action client.
        name: the action's name, as the messages give it.
        limit: seconds of silence (with probes unanswered) after which the server is taken for gone.
    """

    def __init__(self, client: ActionClient, name: str, limit: float) -> None:
        self.client = client
        self.name = name
        self.limit = limit
        self.started = time.monotonic()
        self._lock = threading.Lock()
        self._next_graph = 0.0
        self._graph_missing = False
        self._next_probe = 0.0
        self._first_unanswered: float | None = None  # when the oldest probe of the current silence went out
        self._silent_since: float | None = None  # when the verdict "silent" was first reached (see CONFIRM)
        self._probes: list[Any] = []

    def check(self) -> str | None:
        """None while the server looks alive; else why it is taken for gone (a sentence naming the action).

        Safe from any thread; a check already running in another thread makes this one return None at once.
        """
        if not self._lock.acquire(blocking=False):
            return None
        try:
            if not self._own_side_alive():
                return None  # our context is shut down (a signal): the graph and the silence say nothing of the server
            return self._graph_gone() or self._silent()
        finally:
            self._lock.release()

    def _own_side_alive(self) -> bool:
        """Whether this process's ROS context still runs: once rclpy's signal handler shut it down the graph looks
        empty and nothing arrives, which must not make the goal "lost" before the signal's own cancel is sent."""
        node = getattr(self.client, "_node", None)
        return node is None or bool(node.context.ok())

    def close(self) -> None:
        """Stop waiting for the probes' answers (a server that went away never sends them)."""
        with self._lock:
            probes, self._probes = self._probes, []
        for future in probes:
            if not future.done():
                with contextlib.suppress(Exception):
                    self.client.forget_request(future)

    def _graph_gone(self) -> str | None:
        now = time.monotonic()
        if now < self._next_graph:
            return None
        self._next_graph = now + GRAPH_PERIOD
        if self.client.server_is_ready():
            self._graph_missing = False
            return None
        if not self._graph_missing:  # confirmed on the next look
            self._graph_missing = True
            return None
        # The graph alone is not enough: under load a live server's endpoints can read as missing for a moment (seen
        # in CI: a navigate_through_poses goal failed while its simulator ran on). A server that is really gone
        # also stops sending feedback and status.
        if time.monotonic() - max(self.client.last_heard, self.started) < GRAPH_QUIET:
            return None
        return f"{self.name}: the action server went away (its node left the ROS graph) while the goal was active"

    def _silent(self) -> str | None:
        now = time.monotonic()
        quiet = now - max(self.client.last_heard, self.started)
        if quiet < PROBE_AFTER:
            self._first_unanswered = self._silent_since = None
            self._probes = [f for f in self._probes if not f.done()]
            return None
        if now >= self._next_probe:
            self._next_probe = now + PROBE_PERIOD
            if self._first_unanswered is None:
                self._first_unanswered = now
            with contextlib.suppress(Exception):  # a client being destroyed: the graph check then tells
                self._probes.append(self.client.probe_async())
        asked = 0.0 if self._first_unanswered is None else now - self._first_unanswered
        if quiet < self.limit or asked < self.limit - PROBE_AFTER:
            self._silent_since = None
            return None
        if self._silent_since is None:
            self._silent_since = now
        if now - self._silent_since < CONFIRM:
            return None
        return (
            f"{self.name}: the action server stopped answering while the goal was active (nothing from it for "
            f"{quiet:.1f} s: no feedback, no status, no reply to {len(self._probes)} requests every live server "
            "answers at once) — did its process die?"
        )
