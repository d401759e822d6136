"""Nav2's docking server (opennav_docking) over the Create 3 dock: DockRobot and UndockRobot as step-able tasks.

DockRobot finds the dock (by id in the dock database, or by pose), navigates to its staging pose unless the robot
is already within `dock_prestaging_tolerance` of it (or `navigate_to_staging_pose` is false), detects the dock
(the requested pose must be the real dock, and the dock must be in sight), then hands the final approach to the
Create 3's own dock action, which has its own rules (tb4.sim.dock). Already docked: success at once.
UndockRobot checks the dock type and that the robot is docked, then runs the Create 3 undock within
`max_undocking_time`. Error codes and feedback states are those of nav2_msgs DockRobot / UndockRobot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

from tb4.core.geometry import Pose, wrap_angle
from tb4.nav.tasks import CANCELED, FAILED, RUNNING, SUCCEEDED, TERMINAL, PhaseLog, Task

__all__ = [
    "DockInstance",
    "DockDatabase",
    "DockRobotTask",
    "UndockRobotTask",
    "DockError",
    "CREATE3_DOCK_TYPE",
    "DOCK_ID",
    "DockingServerCore",
]

_T = TypeVar("_T", "DockRobotTask", "UndockRobotTask")

CREATE3_DOCK_TYPE = "create3_dock"
NONE, DOCK_NOT_IN_DB, DOCK_NOT_VALID, FAILED_TO_STAGE = 0, 901, 902, 903
FAILED_TO_DETECT_DOCK, FAILED_TO_CONTROL, FAILED_TO_CHARGE, TIMEOUT, UNKNOWN = 904, 905, 906, 907, 999
NAV_TO_STAGING_POSE, INITIAL_PERCEPTION, CONTROLLING, WAIT_FOR_CHARGE = 1, 2, 3, 4
_DETECTION_YAW = 0.5  # rad: a requested dock pose must face the way the real dock does, within this


class DockError(Exception):
    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


class DockingRobot(Protocol):
    """What docking needs from the simulation (tb4.sim.simulation.Simulation provides it)."""

    dock_pose: tuple[float, float, float]

    @property
    def time(self) -> float: ...

    def is_docked(self) -> bool: ...

    def dock_visible(self) -> bool: ...

    def start_dock(self) -> Any: ...

    def start_undock(self) -> Any: ...


class Navigation(Protocol):
    """What docking needs from the nav core (tb4.nav.server.NavigationCore provides it)."""

    def pose(self) -> Pose | None: ...

    def start_navigate_to_pose(self, goal: Any) -> Task: ...


@dataclass(frozen=True)
class DockInstance:
    id: str
    type: str
    pose: Pose  # the docked robot's pose (map frame)


class DockDatabase:
    """Dock instances by id (one per world: the Create 3 dock) and the one dock plugin type."""

    def __init__(self, docks: list[DockInstance], params: dict[str, Any]) -> None:
        self.docks = {d.id: d for d in docks}
        self.params = params

    def find(self, dock_id: str) -> DockInstance:
        if dock_id not in self.docks:
            known = ", ".join(sorted(self.docks)) or "none"
            raise DockError(DOCK_NOT_IN_DB, f"dock id '{dock_id}' is not in the dock database (known: {known})")
        return self.docks[dock_id]

    def check_type(self, dock_type: str) -> str:
        if dock_type not in ("", CREATE3_DOCK_TYPE):
            raise DockError(DOCK_NOT_VALID, f"no dock plugin of type '{dock_type}' (known: {CREATE3_DOCK_TYPE})")
        return CREATE3_DOCK_TYPE

    def staging_pose(self, dock: Pose) -> Pose:
        """The dock pose moved `staging_x_offset` along its heading and turned by `staging_yaw_offset`."""
        plugin = self.params[CREATE3_DOCK_TYPE]
        off = float(plugin["staging_x_offset"])
        return (
            dock[0] + off * math.cos(dock[2]),
            dock[1] + off * math.sin(dock[2]),
            wrap_angle(dock[2] + float(plugin["staging_yaw_offset"])),
        )


class _DockingTaskBase:
    """Status machine shared by the two tasks (same shape as tb4.nav.tasks.Task: status, cancel, result)."""

    def __init__(self, robot: DockingRobot) -> None:
        self.robot = robot
        self.status = RUNNING
        self.error_code = NONE
        self.error_msg = ""
        self.start_time = robot.time
        self._create3: Any = None

    @property
    def done(self) -> bool:
        return self.status in TERMINAL

    def _finish(self, status: str, code: int = NONE, msg: str = "") -> None:
        if not self.done:
            self.status, self.error_code, self.error_msg = status, code, msg

    def _cancel_children(self) -> None:
        if self._create3 is not None:
            self._create3.cancel()

    def cancel(self) -> None:
        if not self.done:
            self._cancel_children()
            self.status = CANCELED

    def step(self, now: float) -> None:
        if self.done:
            return
        try:
            self._step(now)
        except DockError as exc:
            self._cancel_children()
            self._finish(FAILED, exc.code, str(exc))
        except Exception as exc:  # a bug must not stop the loop: fail the goal with the reason
            self._cancel_children()
            self._finish(FAILED, UNKNOWN, f"internal error in docking: {type(exc).__name__}: {exc}")

    def _step(self, now: float) -> None:
        raise NotImplementedError

    def result(self) -> dict[str, Any]:
        return {"success": self.status == SUCCEEDED, "error_code": self.error_code, "error_msg": self.error_msg}


class DockRobotTask(_DockingTaskBase):
    """One DockRobot goal: stage, detect, let the Create 3 dock, confirm charging."""

    def __init__(
        self,
        robot: DockingRobot,
        nav: Navigation,
        database: DockDatabase,
        dock_pose: Pose,
        navigate_to_staging_pose: bool = True,
        max_staging_time: float = 1000.0,
    ) -> None:
        super().__init__(robot)
        self.nav = nav
        self.database = database
        self.dock_pose = dock_pose
        self.navigate = navigate_to_staging_pose
        self.max_staging_time = max_staging_time
        self.phases = PhaseLog()
        self.state = NAV_TO_STAGING_POSE
        self.staging = database.staging_pose(dock_pose)
        self._nav_task: Task | None = None
        self._staging_started: float | None = None
        if not all(math.isfinite(v) for v in dock_pose):
            self._finish(FAILED, UNKNOWN, f"dock pose must be finite, got {dock_pose}")
        elif not (math.isfinite(max_staging_time) and max_staging_time >= 0.0):
            self._finish(FAILED, UNKNOWN, f"max_staging_time must be a finite number >= 0, got {max_staging_time}")

    def _cancel_children(self) -> None:
        super()._cancel_children()
        if self._nav_task is not None:
            self._nav_task.cancel()

    @property
    def state(self) -> int:
        return self._state

    @state.setter
    def state(self, value: int) -> None:
        self._state = value
        self.phases.mark(self.feedback())

    def feedback(self) -> dict[str, Any]:
        return {"state": self.state, "docking_time": max(0.0, self.robot.time - self.start_time), "num_retries": 0}

    def drain_phase_feedback(self) -> list[dict[str, Any]]:
        """The feedback of every phase entered since the last call: at --rate max a whole phase (the Create 3's
        final approach) can pass between two samples (see PhaseLog)."""
        return self.phases.drain()

    def _step(self, now: float) -> None:
        if self.state == NAV_TO_STAGING_POSE:
            if self.robot.is_docked():
                self._finish(SUCCEEDED)  # already docked (and charging): nothing to do
                return
            if not self._staged(now):
                return
            self.state = INITIAL_PERCEPTION
        if self.state == INITIAL_PERCEPTION:
            real = self.robot.dock_pose
            off = math.hypot(self.dock_pose[0] - real[0], self.dock_pose[1] - real[1])
            limit = float(self.database.params[CREATE3_DOCK_TYPE]["detection_distance"])
            if off > limit or abs(wrap_angle(self.dock_pose[2] - real[2])) > _DETECTION_YAW:
                raise DockError(
                    FAILED_TO_DETECT_DOCK,
                    f"failed initial dock detection: no dock at the requested pose ({off:.2f} m from the dock)",
                )
            if not self.robot.dock_visible():
                raise DockError(FAILED_TO_DETECT_DOCK, "failed initial dock detection: the dock is not in sight")
            self._create3 = self.robot.start_dock()
            self.state = CONTROLLING
        if self.state == CONTROLLING:
            if not _done(self._create3):
                return
            if self._create3.status != SUCCEEDED:
                reason = self._create3.reason or self._create3.status
                raise DockError(FAILED_TO_CONTROL, f"Create 3 dock failed: {reason}")
            self.state = WAIT_FOR_CHARGE
        if self.state == WAIT_FOR_CHARGE:
            if not self.robot.is_docked():
                raise DockError(FAILED_TO_CHARGE, "the robot left the dock before charging started")
            self._finish(SUCCEEDED)

    def _staged(self, now: float) -> bool:
        """True once at the staging pose (or close enough); raises FAILED_TO_STAGE when navigation fails."""
        if self._nav_task is None:
            pose = self.nav.pose()
            if pose is None:
                raise DockError(UNKNOWN, "cannot get the robot pose in the map frame: set an initial pose first")
            # opennav_docking's l2Norm: position and heading error together
            near = math.hypot(
                pose[0] - self.staging[0], pose[1] - self.staging[1], wrap_angle(pose[2] - self.staging[2])
            )
            if not self.navigate or near < float(self.database.params["dock_prestaging_tolerance"]):
                return True
            self._nav_task = self.nav.start_navigate_to_pose(self.staging)
            self._staging_started = now
        task = self._nav_task
        assert self._staging_started is not None
        if task.status == SUCCEEDED:
            return True
        if task.done:
            raise DockError(FAILED_TO_STAGE, f"failed to navigate to the staging pose: {task.error_msg or task.status}")
        if now - self._staging_started > self.max_staging_time:
            task.cancel()
            raise DockError(FAILED_TO_STAGE, f"navigation to the staging pose took over {self.max_staging_time:g} s")
        return False


class UndockRobotTask(_DockingTaskBase):
    """One UndockRobot goal: the Create 3 undock (reverse, turn), bounded by max_undocking_time."""

    def __init__(self, robot: DockingRobot, database: DockDatabase, dock_type: str, max_undocking_time: float) -> None:
        super().__init__(robot)
        self.max_time = max_undocking_time
        try:
            database.check_type(dock_type)
        except DockError as exc:
            self._finish(FAILED, exc.code, str(exc))
            return
        if not (math.isfinite(max_undocking_time) and max_undocking_time > 0.0):
            self._finish(FAILED, UNKNOWN, f"max_undocking_time must be a positive number, got {max_undocking_time}")
        elif not robot.is_docked():
            self._finish(FAILED, DOCK_NOT_VALID, "not docked: there is no dock to undock from")

    def feedback(self) -> dict[str, Any]:
        return {}

    def _step(self, now: float) -> None:
        if self._create3 is None:
            self._create3 = self.robot.start_undock()
        if now - self.start_time > self.max_time:
            raise DockError(FAILED_TO_CONTROL, f"undocking timed out after {self.max_time:g} s")
        if not _done(self._create3):
            return
        if self._create3.status != SUCCEEDED:
            raise DockError(
                FAILED_TO_CONTROL, f"Create 3 undock failed: {self._create3.reason or self._create3.status}"
            )
        self._finish(SUCCEEDED)


def _done(state: Any) -> bool:
    done = state.done
    return bool(done() if callable(done) else done)


#: the id of a robot's own dock in its dock database
DOCK_ID = "home"


class DockingServerCore:
    """Nav2's docking_server for one robot, without ROS: its dock database (the robot's dock, id 'home', type
    'create3_dock') and the docking task it runs, stepped beside the nav core's motion task by the simulator's
    loop. Starting one is a journaled input (tb4.replay), so a run that docks through it replays."""

    def __init__(self, robot: Any, nav: Any) -> None:
        params = nav.params.section("docking_server", "ros__parameters")
        self.database = DockDatabase([DockInstance(DOCK_ID, CREATE3_DOCK_TYPE, tuple(robot.dock_pose))], params)
        self._robot = robot
        self._nav = nav
        self._task: DockRobotTask | UndockRobotTask | None = None

    @property
    def busy(self) -> bool:
        """Whether a docking task runs (the loop then steps every control period)."""
        return self._task is not None and not self._task.done

    def start_dock_robot(
        self, dock_pose: Pose, navigate_to_staging_pose: bool, max_staging_time: float
    ) -> DockRobotTask:
        """A DockRobot goal at `dock_pose` (map frame); it preempts the running docking task."""
        x, y, yaw = dock_pose
        task = DockRobotTask(
            self._robot, self._nav, self.database, (x, y, yaw), navigate_to_staging_pose, max_staging_time
        )
        return self._run(task)

    def start_undock_robot(self, dock_type: str, max_undocking_time: float) -> UndockRobotTask:
        """An UndockRobot goal; it preempts the running docking task."""
        return self._run(UndockRobotTask(self._robot, self.database, dock_type, max_undocking_time))

    def _run(self, task: _T) -> _T:
        if self._task is not None:
            self._task.cancel()
        self._task = task
        return task

    def step(self, now: float) -> None:
        """Step the running docking task (the loop thread, after the nav core's step)."""
        if self._task is not None and not self._task.done:
            self._task.step(now)
