"""What the viewer tracks over time rather than as a latest value: the real-time factor, the driven trail and
the navigation goals' statuses. Each is bounded (a ring, a trimmed table), so memory never grows with a run."""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "RealTimeFactor",
    "Trail",
    "TaskTracker",
    "STATUS_NAMES",
    "ACTIVE_STATUSES",
    "TRAIL_LENGTH",
    "TRAIL_STEP",
]

#: action_msgs/GoalStatus values.
STATUS_NAMES = {
    0: "unknown",
    1: "accepted",
    2: "executing",
    3: "canceling",
    4: "succeeded",
    5: "canceled",
    6: "aborted",
}
ACTIVE_STATUSES = (1, 2, 3)

TRAIL_LENGTH = 4000  # points kept of the driven trail
TRAIL_STEP = 0.05  # m between two trail points


class RealTimeFactor:
    """Sim seconds per wall second over a sliding window of (wall, sim) samples."""

    def __init__(self, window: float = 2.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.window = window
        self.clock = clock
        self._samples: deque[tuple[float, float]] = deque(maxlen=256)

    def add(self, sim_time: float, wall: float | None = None) -> None:
        wall = self.clock() if wall is None else wall
        if self._samples and sim_time < self._samples[-1][1]:
            self._samples.clear()  # the clock went backwards: a restarted simulator
        if self._samples and wall - self._samples[-1][0] < 0.02:
            return  # keep the ring meaningful at any message rate
        self._samples.append((wall, sim_time))
        while len(self._samples) > 2 and wall - self._samples[0][0] > self.window:
            self._samples.popleft()

    def value(self, wall: float | None = None) -> float | None:
        """None until two samples span 0.2 s; 0 when the clock stopped for longer than the window."""
        if len(self._samples) < 2:
            return None
        wall = self.clock() if wall is None else wall
        (w0, s0), (w1, s1) = self._samples[0], self._samples[-1]
        if wall - w1 > self.window:
            return 0.0
        if w1 - w0 < 0.2:
            return None
        return max(0.0, (s1 - s0) / (w1 - w0))


class Trail:
    """The driven path: bounded, points at least TRAIL_STEP apart, numbered so each page gets only new ones."""

    def __init__(self, maxlen: int = TRAIL_LENGTH, step: float = TRAIL_STEP) -> None:
        self.step = step
        self.points: deque[tuple[int, float, float]] = deque(maxlen=maxlen)
        self.seq = 0
        self.epoch = 0  # bumped when the trail restarts; pages then drop what they have

    def add(self, x: float, y: float) -> None:
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        if self.points:
            # Samples may be far apart (a fast simulator, a busy machine): only relocalization restarts the trail.
            _, lx, ly = self.points[-1]
            if math.hypot(x - lx, y - ly) < self.step:
                return
        self.seq += 1
        self.points.append((self.seq, x, y))

    def clear(self) -> None:
        self.points.clear()
        self.epoch += 1

    def since(self, epoch: int, seq: int) -> tuple[bool, list[float], int]:
        """(reset, flat [x, y, ...] points after `seq`, newest seq) for a page that has (epoch, seq)."""
        reset = epoch != self.epoch
        start = -1 if reset else seq
        flat: list[float] = []
        for s, x, y in self.points:
            if s > start:
                flat.extend((round(x, 3), round(y, 3)))
        return reset, flat, self.seq


@dataclass
class _Goal:
    action: str
    goal_id: str
    status: int
    updated: float
    feedback: dict[str, Any] = field(default_factory=dict)


class TaskTracker:
    """Goal statuses and feedback of the navigation actions (from their hidden status/feedback topics).

    The current task is the most recently updated active goal, else the last one that finished.
    """

    MAX_GOALS = 32

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._goals: dict[tuple[str, str], _Goal] = {}

    def _trim(self) -> None:
        if len(self._goals) > self.MAX_GOALS:
            for key, _ in sorted(self._goals.items(), key=lambda kv: kv[1].updated)[: len(self._goals) // 2]:
                del self._goals[key]

    def on_status(self, action: str, statuses: Sequence[tuple[str, int]]) -> list[tuple[str, int]]:
        """Record a status array; returns the (goal_id, status) pairs that changed."""
        now = self.clock()
        changed = []
        for goal_id, status in statuses:
            key = (action, goal_id)
            goal = self._goals.get(key)
            if goal is None:
                self._goals[key] = goal = _Goal(action, goal_id, int(status), now)
                changed.append((goal_id, int(status)))
            elif goal.status != status:
                goal.status, goal.updated = int(status), now
                changed.append((goal_id, int(status)))
        self._trim()
        return changed

    def on_feedback(self, action: str, goal_id: str, feedback: dict[str, Any]) -> None:
        key = (action, goal_id)
        goal = self._goals.get(key)
        if goal is None:
            self._goals[key] = goal = _Goal(action, goal_id, 2, self.clock())
        elif goal.status not in ACTIVE_STATUSES:
            return  # late feedback after the result
        goal.feedback = dict(feedback)
        goal.updated = self.clock()
        self._trim()

    def current(self) -> dict[str, Any] | None:
        if not self._goals:
            return None
        active = [g for g in self._goals.values() if g.status in ACTIVE_STATUSES]
        goal = max(active or self._goals.values(), key=lambda g: g.updated)
        return {
            "action": goal.action,
            "goal_id": goal.goal_id,
            "status": STATUS_NAMES.get(goal.status, str(goal.status)),
            "active": goal.status in ACTIVE_STATUSES,
            **goal.feedback,
        }

    def active_goals(self) -> list[tuple[str, str]]:
        return [(g.action, g.goal_id) for g in self._goals.values() if g.status in ACTIVE_STATUSES]
