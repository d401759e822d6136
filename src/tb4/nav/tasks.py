"""The Task protocol: every Nav2 action the nav core serves is a task stepped in sim time.

The simulator runs one fixed-step loop; a ROS action callback only creates a task, the loop steps it, and the
action server reads `feedback()` / `result()` whose keys are exactly the Nav2 action's field names. Values are
plain Python: poses are (x, y, yaw) tuples in the map frame, builtin_interfaces/Duration fields are float
seconds, WaypointStatus entries are dicts with the message's field names.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tb4.core.geometry import Pose

if TYPE_CHECKING:
    from tb4.nav.costmap import Costmap2D
    from tb4.nav.params import Nav2Params

__all__ = [
    "RUNNING",
    "SUCCEEDED",
    "FAILED",
    "CANCELED",
    "TERMINAL",
    "NOT_LOCALIZED_MSG",
    "Pose",
    "PhaseLog",
    "Task",
    "NavContext",
    "waypoint_status",
    "WaypointStatusCode",
    "path_length",
]

RUNNING = "running"
SUCCEEDED = "succeeded"
FAILED = "failed"
CANCELED = "canceled"
TERMINAL = frozenset({SUCCEEDED, FAILED, CANCELED})

NOT_LOCALIZED_MSG = "not localized: publish an initial pose on 'initialpose' first"


class WaypointStatusCode:
    """nav2_msgs/msg/WaypointStatus constants."""

    PENDING = 0
    COMPLETED = 1
    SKIPPED = 2
    FAILED = 3


def waypoint_status(index: int, pose: Pose, status: int, error_code: int = 0, error_msg: str = "") -> dict[str, Any]:
    """A nav2_msgs/WaypointStatus as a dict (waypoint_pose as an (x, y, yaw) map-frame tuple)."""
    return {
        "waypoint_status": int(status),
        "waypoint_index": int(index),
        "waypoint_pose": (float(pose[0]), float(pose[1]), float(pose[2])),
        "error_code": int(error_code),
        "error_msg": str(error_msg),
    }


@dataclass
class NavContext:
    """What a task may see and do during one step; built by NavigationCore (tests may build their own).

    `pose_fn` returns the localized map-frame pose or None before localization; `local_pose_fn` the pose in
    the local costmap's frame (map when localized, odom before: behaviours work without localization, like
    Nav2's behaviour server working in odom); `velocity_fn` the measured (v, w); `send_fn` forwards a velocity
    command to the base.
    """

    params: Nav2Params
    pose_fn: Callable[[], Pose | None]
    local_pose_fn: Callable[[], Pose]
    velocity_fn: Callable[[], tuple[float, float]]
    send_fn: Callable[[float, float], None]
    local_costmap_fn: Callable[[], Costmap2D | None] = lambda: None
    global_costmap_fn: Callable[[], Costmap2D | None] = lambda: None
    planning_costmap_fn: Callable[[], Costmap2D | None] | None = None
    planner: Any = None
    clear_global_fn: Callable[[], None] = lambda: None
    clear_local_fn: Callable[[], None] = lambda: None
    now: float = 0.0
    last_command: tuple[float, float] = field(default=(0.0, 0.0))

    def pose(self) -> Pose | None:
        return self.pose_fn()

    def local_pose(self) -> Pose:
        return self.local_pose_fn()

    def velocity(self) -> tuple[float, float]:
        return self.velocity_fn()

    def send_velocity(self, v: float, w: float) -> None:
        self.last_command = (float(v), float(w))
        self.send_fn(float(v), float(w))

    def stop(self) -> None:
        self.send_velocity(0.0, 0.0)

    @property
    def local_costmap(self) -> Costmap2D | None:
        return self.local_costmap_fn()

    @property
    def global_costmap(self) -> Costmap2D | None:
        return self.global_costmap_fn()

    def planning_costmap(self) -> Costmap2D | None:
        """Global costmap with the live obstacles of the local window merged in (Nav2's global obstacle layer)."""
        if self.planning_costmap_fn is not None:
            return self.planning_costmap_fn()
        return self.global_costmap

    def clear_costmaps(self) -> None:
        self.clear_global_fn()
        self.clear_local_fn()


class PhaseLog:
    """Feedback kept at the moments a client must see: a docking phase entered, the drive started, a pose passed,
    a recovery begun. Feedback goes out at a bounded wall rate, and at --rate max (or while the server's thread
    waits for a core) such a moment can fall between two samples; the action bridge sends these before each
    sample, as Nav2 reports every one. Bounded: a task nobody serves over ROS keeps only the newest."""

    KEPT = 64

    def __init__(self) -> None:
        self._kept: deque[dict[str, Any]] = deque(maxlen=self.KEPT)

    def mark(self, feedback: dict[str, Any]) -> None:
        self._kept.append(feedback)

    def drain(self) -> list[dict[str, Any]]:
        """The feedback marked since the last call, oldest first."""
        kept = list(self._kept)
        self._kept.clear()
        return kept


class Task:
    """Base class of step-able navigation tasks (one Nav2 action goal each).

    Subclasses implement `_start` (first step), `_step` and the result/feedback dicts; the base keeps the
    status machine, timing and the result code/message.
    """

    name = "task"
    UNKNOWN = 0  # action-specific UNKNOWN error code, overridden by subclasses
    drives = True  # needs the base to move: fails at once while the robot cannot drive (NavigationCore)

    def __init__(self) -> None:
        self.status: str = RUNNING
        self.error_code: int = 0
        self.error_msg: str = ""
        self.start_time: float | None = None
        self.end_time: float | None = None
        self.last_time: float = 0.0
        self._cancel_requested = False
        self.phases = PhaseLog()

    def drain_phase_feedback(self) -> list[dict[str, Any]]:
        """The feedback of the moments marked since the last call (see PhaseLog)."""
        return self.phases.drain()

    # --- life cycle ----------------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        return self.status in TERMINAL

    def elapsed(self, now: float | None = None) -> float:
        if self.start_time is None:
            return 0.0
        end = self.end_time if self.end_time is not None else (self.last_time if now is None else now)
        return max(0.0, end - self.start_time)

    def cancel(self) -> None:
        """Request cancellation; the task becomes 'canceled' at once and stops commanding motion."""
        if self.done:
            return
        self._cancel_requested = True
        self.status = CANCELED
        self.end_time = self.last_time if self.start_time is not None else None
        self._on_cancel()

    def abort(self, code: int, msg: str, now: float) -> None:
        """End a running task as failed from outside (the base stopped for good): its sub-tasks are canceled.

        Args:
            code: the action's error code for the result.
            msg: why, for the result's error_msg.
            now: sim time of the end.
        """
        if self.done:
            return
        if self.start_time is None:
            self.start_time = now
        self._on_cancel()
        self._fail(code, msg, now)

    def step(self, ctx: NavContext, now: float) -> str:
        """Advance the task to sim time `now`; returns the status."""
        if self.done:
            return self.status
        if self.start_time is None:
            self.start_time = now
        self.last_time = now
        ctx.now = now
        try:
            self._step(ctx, now)
        except Exception as exc:  # a bug must not kill the sim loop: fail the goal with the reason instead
            self._fail(self.UNKNOWN, f"internal error in {self.name}: {type(exc).__name__}: {exc}", now)
        if self.done and self.status != SUCCEEDED:
            ctx.stop()
        return self.status

    def _succeed(self, now: float) -> None:
        self.status = SUCCEEDED
        self.error_code = 0
        self.error_msg = ""
        self.end_time = now

    def _fail(self, code: int, msg: str, now: float) -> None:
        self.status = FAILED
        self.error_code = int(code)
        self.error_msg = msg
        self.end_time = now

    # --- to override ---------------------------------------------------------------------------------
    def _step(self, ctx: NavContext, now: float) -> None:
        raise NotImplementedError

    def _on_cancel(self) -> None:
        """Hook: cancel sub-tasks."""

    def feedback(self) -> dict[str, Any]:
        return {}

    def result(self) -> dict[str, Any]:
        return {"error_code": self.error_code, "error_msg": self.error_msg}


def path_length(path: np.ndarray) -> float:
    if path is None or len(path) < 2:
        return 0.0
    return float(np.hypot(*np.diff(path[:, :2], axis=0).T).sum())
