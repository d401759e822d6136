"""Localization error as `tb4 run` shows it: each amcl_pose beside the ground truth of the same sim time.

amcl_pose comes after filter updates (sparse), ground_truth at 20 Hz: the estimate is paired with the truth
sample nearest in stamp, within a tolerance, so a late message never pairs with a pose of another moment. The two
come from two writers, so an estimate can arrive before the truth of its time (the last one as the robot stops,
often): it waits, a few at most, until a truth at or after its stamp has come.
"""

from __future__ import annotations

import bisect
import math
from collections import deque
from collections.abc import Callable

from tb4.core.geometry import wrap_angle

Pose = tuple[float, float, float]

__all__ = ["LocalizationErrorTracker"]


class LocalizationErrorTracker:
    def __init__(self, max_gap: float = 0.06, history: int = 400, waiting: int = 8) -> None:
        self.max_gap = max_gap
        self._times: deque[float] = deque(maxlen=history)
        self._poses: deque[Pose | Callable[[], Pose]] = deque(maxlen=history)
        self._waiting: deque[tuple[float, Pose]] = deque(maxlen=waiting)  # estimates ahead of the truth
        self.position_error: float | None = None
        self.heading_error_deg: float | None = None

    def add_truth(self, t: float, x: float, y: float, yaw: float) -> float | None:
        """Record a truth sample; returns the position error of an estimate that was waiting for it, if any."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            return None
        return self._append(t, (x, y, yaw))

    def add_truth_later(self, t: float, pose: Callable[[], Pose]) -> float | None:
        """A truth sample whose pose `pose()` decodes only if an estimate pairs with it: of 20 samples a second
        only those beside an amcl_pose are ever read. Returns as add_truth."""
        if not math.isfinite(t):
            return None
        return self._append(t, pose)

    def _append(self, t: float, pose: Pose | Callable[[], Pose]) -> float | None:
        if self._times and t < self._times[-1]:  # the clock went back (a new run): start over
            self._times.clear()
            self._poses.clear()
            self._waiting.clear()
        self._times.append(t)
        self._poses.append(pose)
        # truths come in stamp order, so nothing nearer will come for an estimate at or before this one; every such
        # estimate is paired now, whatever came between (a hostile far-future stamp must not hold the others back)
        due = [w for w in self._waiting if w[0] <= t]
        if not due:
            return None
        self._waiting = deque((w for w in self._waiting if w[0] > t), maxlen=self._waiting.maxlen)
        error = None
        for stamp, estimate in due:
            paired = self._pair(stamp, estimate)
            error = error if paired is None else paired
        return error

    def add_estimate(self, t: float, x: float, y: float, yaw: float) -> float | None:
        """Pair the estimate with the truth of its time; returns the position error (m), or None when unpaired or
        when it waits for a truth still to come (add_truth then returns its error)."""
        if not all(math.isfinite(v) for v in (t, x, y, yaw)):
            return None
        if not self._times or t > self._times[-1]:
            self._waiting.append((t, (x, y, yaw)))
            return None
        return self._pair(t, (x, y, yaw))

    def _pair(self, t: float, estimate: Pose) -> float | None:
        times = list(self._times)
        i = bisect.bisect_left(times, t)
        best = min((j for j in (i - 1, i) if 0 <= j < len(times)), key=lambda j: abs(times[j] - t))
        if abs(times[best] - t) > self.max_gap:
            return None
        truth = self._poses[best]
        if callable(truth):
            truth = self._poses[best] = truth()
        if not all(math.isfinite(v) for v in truth):  # a decoded pose add_truth would have dropped: no pairing
            return None
        (x, y, yaw), (tx, ty, tyaw) = estimate, truth
        self.position_error = math.hypot(x - tx, y - ty)
        self.heading_error_deg = abs(math.degrees(wrap_angle(yaw - tyaw)))
        return self.position_error
