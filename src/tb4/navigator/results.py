"""TaskResult and RunningTask (upstream names and values) and readable names for action goal statuses."""

from __future__ import annotations

from enum import Enum

from action_msgs.msg import GoalStatus

__all__ = ["TaskResult", "RunningTask", "status_name", "task_result_of"]


class TaskResult(Enum):
    """The outcome of a navigation task, as Nav2 Simple Commander reports it."""

    UNKNOWN = 0
    SUCCEEDED = 1
    CANCELED = 2
    FAILED = 3


class RunningTask(Enum):
    """What a task method started (Kilted): pass it to isTaskComplete(task=...) and getFeedback(task=...).

    A method returns None instead when the server rejected the goal. Only COMPUTE_AND_TRACK_ROUTE is tracked apart
    (it runs beside a follow_path or waypoint task); every other value reports on the one current task.
    """

    NONE = 0
    NAVIGATE_TO_POSE = 1
    NAVIGATE_THROUGH_POSES = 2
    FOLLOW_PATH = 3
    FOLLOW_WAYPOINTS = 4
    FOLLOW_GPS_WAYPOINTS = 5
    SPIN = 6
    BACKUP = 7
    DRIVE_ON_HEADING = 8
    ASSISTED_TELEOP = 9
    DOCK_ROBOT = 10
    UNDOCK_ROBOT = 11
    COMPUTE_AND_TRACK_ROUTE = 12


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
