"""Stage 3, execute: run a checked Plan on the navigator, one call at a time, and stop at the first failure.

Everything happens on the calling thread, the navigator is never touched from another one: goals are started
with Nav2's non-blocking calls (goToPose, goThroughPoses, followWaypoints; the program's blocking startToPose &
co. are their TurtleBot 4 wrappers), behaviours (spin, backup, driveOnHeading) start a task, and this thread
waits for the task with the navigator's own event-driven isTaskComplete() (it returns as soon as the result
arrives). When the run-time budget is spent, or `stop` is set from another thread, this thread cancels the
task itself. Every task step's result is compared with the real `tb4.navigator.TaskResult`: anything but
SUCCEEDED stops the plan, and so does a dock or undock that does not report success.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tb4.language.bounded_format import bounded_text, clip
from tb4.language.limits import DEFAULT_LIMITS, Limits
from tb4.language.vocabulary import ALLOWED_METHODS, BEHAVIOUR_METHODS, GOAL_METHODS, Plan, Pose, Step

__all__ = ["ExecutionReport", "execute_plan"]


@dataclass
class ExecutionReport:
    """What happened when a plan ran: steps completed, and why it stopped early (empty if it did not)."""

    completed: int = 0
    total: int = 0
    stopped: str = ""

    @property
    def ok(self) -> bool:
        return not self.stopped and self.completed == self.total


_TIMEOUT = "timeout"


class _Stop(Exception):
    """The plan stops here; the message says why."""


def _task_result() -> Any:
    # Imported when a plan runs, not when this module loads: planning and the offline tools need no ROS.
    from tb4.navigator import TaskResult

    return TaskResult


def execute_plan(
    plan: Plan,
    navigator: Any,
    limits: Limits = DEFAULT_LIMITS,
    should_stop: Callable[[], bool] | None = None,
    stop: threading.Event | None = None,
) -> ExecutionReport:
    """Replay a checked plan on the navigator within `limits.max_run_seconds`; see the module docstring.

    `stop` (an Event another thread may set) and `should_stop` ask the plan to end: the running task is
    cancelled by this thread and no further step runs. A navigator call that raises stops the plan too (the
    report says which step and what was raised; a task it may have started is cancelled).
    """
    run = _Run(navigator, limits, stop or threading.Event(), should_stop)
    report = ExecutionReport(total=len(plan.steps))
    for step in plan.steps:
        try:
            run.check(step)
            run.step(step)
        except _Stop as why:
            report.stopped = str(why)
            break
        except Exception as exc:  # noqa: BLE001 - reported with the step; the caller decides what it means
            report.stopped = clip(f"{step.describe()} raised {type(exc).__name__}: {exc}", limits.max_message)
            if step.method in GOAL_METHODS or step.method in BEHAVIOUR_METHODS:
                with contextlib.suppress(Exception):  # best effort: the task may not have started
                    navigator.cancelTask()
            break
        report.completed += 1
    return report


class _Run:
    def __init__(
        self, navigator: Any, limits: Limits, stop: threading.Event, should_stop: Callable[[], bool] | None
    ) -> None:
        self.nav = navigator
        self.limits = limits
        self.stop = stop
        self.should_stop = should_stop
        self.deadline = time.monotonic() + limits.max_run_seconds
        self.TaskResult = _task_result()
        self._idle = threading.Event()  # never set: a plain sleep while a cancel lands

    def _stop_reason(self) -> str:
        if self.stop.is_set() or (self.should_stop is not None and self.should_stop()):
            return "stopped on request"
        if time.monotonic() > self.deadline:
            return f"run-time limit of {self.limits.max_run_seconds:g} s reached"
        return ""

    def check(self, step: Step) -> None:
        if step.method not in ALLOWED_METHODS:  # plans only come from the planner; belt and braces
            raise _Stop(f"method {step.method!r} is not allowed")
        why = self._stop_reason()
        if why:
            raise _Stop(why)

    def step(self, step: Step) -> None:
        method = step.method
        if method in GOAL_METHODS:
            arg = step.args[0]
            target = self._stamped(arg) if isinstance(arg, Pose) else [self._stamped(p) for p in arg]
            started = getattr(self.nav, GOAL_METHODS[method])(target)
            self._follow(step, started, self.limits.max_task_seconds)
        elif method in BEHAVIOUR_METHODS:
            started = getattr(self.nav, method)(*step.args)
            allowance = float(step.args[-1])  # time_allowance is the last parameter of every behaviour
            self._follow(step, started, min(self.limits.max_task_seconds, allowance + self.limits.task_grace_seconds))
        elif method in ("dock", "undock"):
            # Blocking Create 3 actions, bounded by the navigator's own result timeout; True means it worked.
            if getattr(self.nav, method)() is not True:
                raise _Stop(f"{method} did not succeed")
        else:
            getattr(self.nav, method)(*step.args)

    def _stamped(self, pose: Pose) -> Any:
        return self.nav.getPoseStamped([pose.x, pose.y], pose.degrees)

    def _follow(self, step: Step, started: Any, limit: float) -> None:
        """Wait for the task `step` started, cancel it if it outlives `limit` or the budget, check its result."""
        if not started:  # None (Kilted's RunningTask API) or False (Jazzy-era navigators): rejected
            raise _Stop(f"{step.describe()} was rejected{self._error_text()}")
        step_deadline = min(time.monotonic() + limit, self.deadline)
        why = self._wait(step_deadline, self.stop)
        if why is not None:
            if why == _TIMEOUT:
                why = self._stop_reason() or f"did not finish within {limit:g} s"
            self.nav.cancelTask()
            self._wait(time.monotonic() + self.limits.task_grace_seconds, self._idle)
            raise _Stop(f"{step.describe()} cancelled: {why}")
        result = self.nav.getResult()
        if result is not self.TaskResult.SUCCEEDED:
            name = getattr(result, "name", None) or bounded_text(result, 40)
            raise _Stop(f"{step.describe()} ended {name}{self._error_text()}")

    def _wait(self, until: float, wake: threading.Event) -> str | None:
        """Wait for the current task to complete: None when it did, else why not (_TIMEOUT once `until` passed,
        or the stop reason). Sleeps are cut short by `wake`; with the real navigator isTaskComplete() itself
        blocks on its result event, so the result is seen as soon as it arrives."""
        poll = self.limits.poll_seconds
        while True:
            asked = time.monotonic()
            if self.nav.isTaskComplete():
                return None
            now = time.monotonic()
            if now >= until:
                return _TIMEOUT
            if wake is self.stop:
                why = self._stop_reason()
                if why:
                    return why
            # Never a busy loop, whatever the navigator: sleep what is left of the poll period.
            wake.wait(max(0.0, min(poll - (now - asked), until - now)))

    def _error_text(self) -> str:
        getter = getattr(self.nav, "getTaskError", None)
        if getter is None:
            return ""
        try:
            code, msg = getter()
        except Exception:  # noqa: BLE001 - the reason is a courtesy; the failure itself is already known
            return ""
        return f" (error {code}: {bounded_text(msg, 120)})" if code or msg else ""
