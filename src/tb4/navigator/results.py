"""TaskResult (upstream values) and readable names for action goal statuses."""

from __future__ import annotations

from enum import Enum

from action_msgs.msg import GoalStatus

__all__ = ["TaskResult", "status_name", "task_result_of"]


class TaskResult(Enum):
    """The outcome of a navigation task, as Nav2 Simple Commander reports it."""

    UNKNOWN = 0
    SUCCEEDED = 1
    CANCELED = 2
    FAILED = 3


_STATUS_NAMES = {
    GoalStatus.STATUS_UNKNOWN: "UNKNOWN",
    GoalStatus.STATUS_ACCEPTED: "ACCEPTED",
    GoalStatus.STATUS_EXECUTING: "EXECUTING",
    GoalStatus.STATUS_CANCELING: "CANCELING",
    GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED",
    GoalStatus.STATUS_CANCELED: "CANCELED",
    GoalStatus.STATUS_ABORTED: "ABORTED",
}


def status_name(status: int | None) -> str:
    """'ABORTED' for 6, 'REJECTED' for None (no goal ran): what upstream printed as 'status code: None'."""
    if status is None:
        return "REJECTED"
    return _STATUS_NAMES.get(status, f"status {status}")


def task_result_of(status: int | None) -> TaskResult:
    if status == GoalStatus.STATUS_SUCCEEDED:
        return TaskResult.SUCCEEDED
    if status == GoalStatus.STATUS_CANCELED:
        return TaskResult.CANCELED
    if status == GoalStatus.STATUS_ABORTED:
        return TaskResult.FAILED
    return TaskResult.UNKNOWN
