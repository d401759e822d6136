"""The status of a Create 3 goal in the simulator (dock, undock, the drive goals, led_animation,
audio_note_sequence): running until it ends once — succeeded, failed or canceled — with a reason; never after."""

from __future__ import annotations

__all__ = ["RUNNING", "SUCCEEDED", "FAILED", "CANCELED", "GoalState"]

RUNNING = "running"
SUCCEEDED = "succeeded"
FAILED = "failed"
CANCELED = "canceled"


class GoalState:
    """`kind` names the goal ("dock", "drive_distance", "led_animation", ...); `status` and `reason` say how it
    ended. The first end wins: finishing or canceling an ended goal changes nothing."""

    def __init__(self, kind: str, status: str = RUNNING, reason: str = "") -> None:
        self.kind = kind
        self.status = status
        self.reason = reason

    @property
    def done(self) -> bool:
        return self.status != RUNNING

    def cancel(self) -> None:
        """End it canceled (a moving goal's robot is stopped by the simulation on its next step)."""
        self.finish(CANCELED, f"{self.kind} canceled")

    def finish(self, status: str, reason: str = "") -> None:
        if self.status == RUNNING:
            self.status, self.reason = status, reason
