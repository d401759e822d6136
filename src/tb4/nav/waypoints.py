"""FollowWaypoints as a step-able task: the waypoint follower's job (navigate to each pose in turn, pause, record
the missed ones), built on NavigateToPose."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from tb4.core.geometry import Pose
from tb4.nav.navigate import NavigateToPose, as_goal_pose
from tb4.nav.tasks import FAILED, NOT_LOCALIZED_MSG, SUCCEEDED, NavContext, Task, WaypointStatusCode, waypoint_status

__all__ = ["FollowWaypoints"]


class FollowWaypoints(Task):
    """Navigate to each waypoint in turn, pausing `waypoint_pause_duration` ms at each; missed ones are recorded."""

    name = "follow_waypoints"
    UNKNOWN, TASK_EXECUTOR_FAILED, NO_VALID_WAYPOINTS, STOP_ON_MISSED_WAYPOINT = 600, 601, 602, 603

    def __init__(
        self,
        goals: Sequence[Sequence[float]],
        number_of_loops: int = 0,
        goal_index: int = 0,
        stop_on_failure: bool | None = None,
        pause_duration: float | None = None,
    ) -> None:
        super().__init__()
        self._raw_goals = list(goals)
        self.goals: list[Pose] = []
        self.number_of_loops = int(number_of_loops)
        self.current_waypoint = int(goal_index)
        self.loop = 0
        self.stop_on_failure = stop_on_failure
        self.pause_duration = pause_duration
        self.missed_waypoints: list[dict[str, Any]] = []
        self.visited: list[int] = []
        self._nav: NavigateToPose | None = None
        self._pause_until: float | None = None
        self._started = False

    def _step(self, ctx: NavContext, now: float) -> None:
        if not self._started:
            self._started = True
            wf = ctx.params.waypoint_follower
            if self.stop_on_failure is None:
                self.stop_on_failure = bool(wf["stop_on_failure"])
            if self.pause_duration is None:
                pause = wf["wait_at_waypoint"]
                self.pause_duration = float(pause["waypoint_pause_duration"]) / 1000.0 if pause["enabled"] else 0.0
            try:
                self.goals = [as_goal_pose(g) for g in self._raw_goals]
            except (TypeError, ValueError) as exc:
                self._fail(self.NO_VALID_WAYPOINTS, f"invalid waypoint: {exc}", now)
                return
            if not self.goals:
                self._fail(self.NO_VALID_WAYPOINTS, "no waypoints given", now)
                return
            if not 0 <= self.current_waypoint < len(self.goals):
                self._fail(
                    self.NO_VALID_WAYPOINTS,
                    f"goal_index {self.current_waypoint} is outside the {len(self.goals)} waypoints given",
                    now,
                )
                return
            if self.number_of_loops < 0:
                self._fail(self.NO_VALID_WAYPOINTS, f"number_of_loops must be >= 0, got {self.number_of_loops}", now)
                return
            if ctx.pose() is None:
                self._fail(self.UNKNOWN, NOT_LOCALIZED_MSG, now)
                return
        if self._pause_until is not None:
            ctx.stop()
            if now + 1e-9 < self._pause_until:
                return
            self._pause_until = None
            self._advance(now)
            if self.done:
                return
        if self._nav is None:
            self._nav = NavigateToPose(self.goals[self.current_waypoint])
            self.phases.mark(self.feedback())  # each waypoint begun, even one passed between two samples
        self._nav.step(ctx, now)
        if not self._nav.done:
            return
        nav, self._nav = self._nav, None
        if nav.status == SUCCEEDED:
            self.visited.append(self.current_waypoint)
            self._pause_until = now + float(self.pause_duration or 0.0)
            return
        if nav.status == FAILED:
            self.missed_waypoints.append(
                waypoint_status(
                    self.current_waypoint,
                    self.goals[self.current_waypoint],
                    WaypointStatusCode.FAILED,
                    nav.error_code,
                    nav.error_msg,
                )
            )
            if self.stop_on_failure:
                self._fail(
                    self.STOP_ON_MISSED_WAYPOINT,
                    f"failed to reach waypoint {self.current_waypoint} and stop_on_failure is set: {nav.error_msg}",
                    now,
                )
                return
        self._advance(now)

    def _advance(self, now: float) -> None:
        self.current_waypoint += 1
        if self.current_waypoint >= len(self.goals):
            if self.loop >= self.number_of_loops:
                self.current_waypoint = len(self.goals) - 1
                self._succeed(now)
                return
            self.loop += 1
            self.current_waypoint = 0

    def _on_cancel(self) -> None:
        if self._nav is not None:
            self._nav.cancel()

    def abort(self, code: int, msg: str, now: float) -> None:
        """End it failed from outside; the waypoint being driven to is recorded as missed.

        Args:
            code: the action's error code for the result.
            msg: why, for the result's error_msg and the missed waypoint.
            now: sim time of the end.
        """
        if not self.done and self._nav is not None and 0 <= self.current_waypoint < len(self.goals):
            self.missed_waypoints.append(
                waypoint_status(
                    self.current_waypoint, self.goals[self.current_waypoint], WaypointStatusCode.FAILED, code, msg
                )
            )
        super().abort(code, msg, now)

    @property
    def navigation(self) -> NavigateToPose | None:
        return self._nav

    def feedback(self) -> dict[str, Any]:
        return {"current_waypoint": int(self.current_waypoint)}

    def result(self) -> dict[str, Any]:
        return {
            "missed_waypoints": [dict(m) for m in self.missed_waypoints],
            "error_code": self.error_code,
            "error_msg": self.error_msg,
        }
