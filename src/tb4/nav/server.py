"""NavigationCore: the whole Nav2-like stack behind one object, stepped by the simulator loop in sim time.

It owns the global and local costmaps, the planner, the localizer and the active motion task. ROS callbacks
(in tb4.ros) only call the `start_*` / service methods here; the simulator loop calls `step(now)` at 20 Hz,
which updates the local costmap from the latest scan (10 Hz), steps the task and sends its velocity. One
motion task runs at a time: starting another cancels (preempts) the running one, as a robot has one base. While
the base cannot drive for good (`RobotInterface.drive_disabled`: a flat battery), a task that drives fails at once
with that reason instead of waiting out the progress checker.

Every ROS callback goes through this one facade, and each method hands the work to the component that does it, so
read it by section: robot state (poses, velocity), costmaps (the local one's update, the one planning uses, the
clearing services, a new map), localization (initial pose, global localization), the loop (`step`), tasks (start,
cancel, teleop), lifecycle (pause, resume) and the planning services (paths, smoothing, validity). The components
themselves live beside it: costmap.py, local_costmap.py, planner.py, smoother.py, make_localizer.py and the task
modules (navigate.py, waypoints.py, follow_path.py, behaviors.py).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, Concatenate, ParamSpec, Protocol, TypeVar

import numpy as np

from tb4.core.geometry import Pose
from tb4.core.maps import OccupancyMap
from tb4.nav.amcl import Amcl
from tb4.nav.basic_localizers import Localizer
from tb4.nav.behaviors import AssistedTeleop, BackUp, DriveOnHeading, Spin, Wait
from tb4.nav.costmap import Costmap2D, GlobalCostmap, StaticLayers
from tb4.nav.follow_path import FollowPath
from tb4.nav.local_costmap import LocalCostmap
from tb4.nav.make_localizer import LOCALIZATION_MODES, make_localizer
from tb4.nav.navigate import NavigateThroughPoses, NavigateToPose
from tb4.nav.params import Nav2Params, load_nav2_params
from tb4.nav.planner import Planner, PlanResult
from tb4.nav.smoother import SmoothResult, is_path_valid, smooth_path
from tb4.nav.tasks import FAILED, NOT_LOCALIZED_MSG, NavContext, Task
from tb4.nav.waypoints import FollowWaypoints

__all__ = ["RobotInterface", "NavigationCore", "NotLocalizedError", "PAUSED_MSG", "LOCALIZATION_MODES"]

PAUSED_MSG = "navigation is paused (lifecycle): resume it before sending goals"
_P = ParamSpec("_P")
_T = TypeVar("_T", bound=Task)
SCAN_PERIOD = 0.1  # s of sim time between the localizer's looks at the lidar (the RPLIDAR's 10 Hz)


class RobotInterface(Protocol):
    """What the core needs from the robot (tb4.sim.simulation.Simulation provides it)."""

    @property
    def time(self) -> float: ...

    def odometry(self) -> Any:  # .x .y .yaw .v .w
        ...

    def scan(self) -> Any:  # LaserScan: ranges, angle_min, angle_increment, range_max
        ...

    def set_velocity_command(self, v: float, w: float) -> tuple[bool, str]: ...

    def drive_disabled(self) -> str:  # why the base cannot drive until it is docked ('' when it can)
        ...


class NotLocalizedError(RuntimeError):
    """A request needs the map pose but no initial pose was given (ROS layer: TF_ERROR 202 / 302)."""

    def __init__(self) -> None:
        super().__init__(NOT_LOCALIZED_MSG)


def _rejected(task: _T, code: int, msg: str) -> _T:
    task.status = FAILED
    task.error_code = code
    task.error_msg = msg
    task.start_time = task.end_time = 0.0
    return task


def _starter(task_type: Callable[_P, _T]) -> Callable[Concatenate[NavigationCore, _P], _T]:
    """A NavigationCore method that builds `task_type` from its arguments and starts it (preempting the running
    task); its signature is the task's own, for callers and for mypy."""

    def start(self: NavigationCore, /, *args: _P.args, **kwargs: _P.kwargs) -> _T:
        return self._start(task_type(*args, **kwargs))

    start.__doc__ = f"Start a {getattr(task_type, '__name__', 'task')} task (see its class for the arguments)."
    return start


class NavigationCore:
    """Costmaps + planner + controller + localizer + the active task, driven by `step(now)`."""

    def __init__(
        self,
        grid: OccupancyMap,
        params: Nav2Params | None = None,
        robot: RobotInterface | None = None,
        localization: str = "odometry",
        seed: int = 0,
        _layers: StaticLayers | None = None,
    ):
        self._construction: dict[str, Any] = {"grid": grid, "params": params, "localization": localization}
        self.params = params or load_nav2_params()
        self.robot = robot
        self.global_costmap = GlobalCostmap(grid, self.params.costmap_params("global"), _layers)
        # the map's static layers as built now, before any LoadMap: what a reset's costmap on this map takes again
        self._layers = self.global_costmap.layers
        local_params = self.params.costmap_params("local")
        self.local_costmap = LocalCostmap(local_params, self.global_costmap)  # map frame, once localized
        self._odom_local = LocalCostmap(local_params, None)  # odom frame, before localization
        pl = self.params.planner
        self.planner = Planner(tolerance=float(pl["tolerance"]), allow_unknown=bool(pl["allow_unknown"]))
        self.localization = localization
        self.localizer: Localizer | Amcl = make_localizer(localization, grid, self.params, robot, self.odom_pose, seed)
        self._last_scan_look = -math.inf
        self.grid = grid
        self.task: Task | None = None
        self._finished: Task | None = None
        self.paused = False
        self.now = 0.0
        self._last_control = -math.inf
        self._last_costmap = -math.inf
        # a reader's fresh view of an idle robot's local costmap, and (sim time, the costmap it was made from)
        self._view: LocalCostmap | None = None
        self._view_of: tuple[float, Costmap2D] | None = None
        self._last_global_costmap = -math.inf
        # sim seconds between two updates of each costmap (its update_frequency)
        self._local_costmap_period = 1.0 / float(self.params.local_costmap["update_frequency"])
        self._global_costmap_period = 1.0 / float(self.params.global_costmap["update_frequency"])
        self.ctx = NavContext(
            params=self.params,
            pose_fn=self.pose,
            local_pose_fn=self.local_pose,
            velocity_fn=self.velocity,
            send_fn=self._send,
            local_costmap_fn=self.current_local_costmap,
            global_costmap_fn=lambda: self.global_costmap.costmap,
            planning_costmap_fn=self.planning_costmap,
            planner=self.planner,
            clear_global_fn=self.clear_global,
            clear_local_fn=self.clear_local,
        )

    def reset(self, seed: int) -> None:
        """Back to the stack this core was built as, with `seed` (the localizer's): no task, no initial pose,
        fresh costmaps on the map it was built with, the clock at 0. The running task, if any, is canceled first.
        The same object, built by the same code as a new NavigationCore with that seed: a reset core beside a reset
        robot steps as a new pair does, to the last bit.

        Args:
            seed: the new run's seed.
        """
        self.cancel()
        kwargs = dict(self._construction)
        self.__init__(robot=self.robot, seed=seed, _layers=self._layers, **kwargs)  # type: ignore[misc]

    # --- robot state ---------------------------------------------------------------------------------
    def _odom(self) -> Any:
        if self.robot is None:
            raise RuntimeError("NavigationCore has no robot attached")
        return self.robot.odometry()

    def odom_pose(self) -> Pose:
        o = self._odom()
        return (float(o.x), float(o.y), float(o.yaw))

    def pose(self) -> Pose | None:
        """Localized map-frame pose (what amcl_pose reports), or None before an initial pose."""
        return self.localizer.map_pose(self.odom_pose())

    def local_pose(self) -> Pose:
        p = self.pose()
        return p if p is not None else self.odom_pose()

    def velocity(self) -> tuple[float, float]:
        o = self._odom()
        return (float(o.v), float(o.w))

    def _send(self, v: float, w: float) -> None:
        if self.robot is not None:
            self.robot.set_velocity_command(v, w)

    # --- costmaps ------------------------------------------------------------------------------------
    def _active_local(self) -> LocalCostmap:
        return self.local_costmap if self.localizer.is_localized else self._odom_local

    def current_local_costmap(self) -> Costmap2D:
        """The local costmap in use, up to date: in `local_frame` ('map' once localized, 'odom' before).

        Reading it changes nothing, so a run is the same whoever reads the costmaps. While a task runs, `step`
        keeps it up to date at its update_frequency; while the robot is idle, `step` leaves it (an idle robot stays
        cheap to simulate) and a reader gets a view updated at that frequency on a copy (`_local_view`)."""
        return self._local_view(self._active_local()).costmap

    def _local_view(self, local: LocalCostmap) -> LocalCostmap:
        """What a reader sees of `local`: itself while a task runs (tasks read nothing else, so what they do never
        depends on a reader), else a copy updated from the scan once per update period; a clear shows at once
        (the cleared costmap, until the next update period)."""
        period = self._local_costmap_period - 1e-6
        if self.robot is None or self.active or self.now - self._last_costmap < period:
            return local
        made_at, made_from = self._view_of if self._view_of is not None else (-math.inf, None)
        if self.now - made_at < period:
            return self._view if self._view is not None and made_from is local.costmap else local
        view = local.copy()
        x, y, hits, free = self._scan_points()
        view.update(x, y, hits, x, y, free)
        self._view, self._view_of = view, (self.now, local.costmap)
        return view

    @property
    def local_frame(self) -> str:
        return "map" if self.localizer.is_localized else "odom"

    def _refresh_local_costmap(self) -> None:
        """Update the local costmap if its update period has passed (costmap update_frequency, in sim time)."""
        if self.robot is not None and self.now - self._last_costmap >= self._local_costmap_period - 1e-6:
            self._last_costmap = self.now
            self.update_local_costmap()

    def _scan_points(self) -> tuple[float, float, np.ndarray, np.ndarray]:
        """The robot's position and its current scan as map points: hits, and the ends of the rays that hit
        nothing (to clear along); the laser is at the robot centre."""
        assert self.robot is not None
        scan = self.robot.scan()
        x, y, yaw = self.local_pose()
        ranges = np.asarray(scan.ranges, dtype=np.float64)
        angles = scan.angle_min + np.arange(len(ranges)) * scan.angle_increment + yaw
        hit = np.isfinite(ranges) & (ranges >= scan.range_min) & (ranges <= scan.range_max)
        hits = np.stack([x + ranges[hit] * np.cos(angles[hit]), y + ranges[hit] * np.sin(angles[hit])], axis=1)
        reach = min(float(scan.range_max), float(self.params.local_costmap["obstacle_layer"]["raytrace_max_range"]))
        miss = ~hit
        free = np.stack([x + reach * np.cos(angles[miss]), y + reach * np.sin(angles[miss])], axis=1)
        return x, y, hits, free

    def update_local_costmap(self) -> None:
        """Mark/clear the local costmap from the robot's current scan (laser at the robot centre)."""
        if self.robot is None:
            return
        x, y, hits, free = self._scan_points()
        self._active_local().update(x, y, hits, x, y, free)
        # the global costmap is in the map frame, and takes the scan at its own update_frequency (as Nav2's costmap
        # whose obstacle layer keeps only the latest observation); planning sees the local window's marks meanwhile
        period = self._global_costmap_period
        if self.localizer.is_localized and self.now - self._last_global_costmap >= period - 1e-6:
            self._last_global_costmap = self.now
            self.global_costmap.update_obstacles(x, y, hits, free)

    def planning_costmap(self) -> Costmap2D:
        """The global costmap with the local window's live obstacles merged in (Nav2's global obstacle layer).
        Reading it changes nothing (see `current_local_costmap`)."""
        glob = self.global_costmap.costmap
        if not self.localizer.is_localized:
            return glob
        loc = self._local_view(self.local_costmap).costmap
        res = glob.resolution
        if abs(loc.resolution - res) > 1e-9:
            return glob
        c0 = int(round((loc.origin_x - glob.origin_x) / res))
        r0 = int(round((loc.origin_y - glob.origin_y) / res))
        gr0, gc0 = max(r0, 0), max(c0, 0)
        gr1, gc1 = min(r0 + loc.data.shape[0], glob.data.shape[0]), min(c0 + loc.data.shape[1], glob.data.shape[1])
        if gr0 >= gr1 or gc0 >= gc1:
            return glob
        merged = glob.copy()
        window = merged.data[gr0:gr1, gc0:gc1]
        live = loc.data[gr0 - r0 : gr1 - r0, gc0 - c0 : gc1 - c0]
        known = window != 255
        window[known] = np.maximum(window[known], live[known])
        merged.layer = "global"
        return merged

    def clear_global(self) -> None:
        self.global_costmap.clear()

    def _catch_up_local(self) -> None:
        """Before a clear of an idle robot's local costmap (an input, so it may change the world): bring it up to
        date first, as it would be had `step` kept updating it, so the clear acts on what a reader saw."""
        if not self.active:
            self._refresh_local_costmap()

    def clear_local(self) -> None:
        self._catch_up_local()
        self.local_costmap.clear()
        self._odom_local.clear()

    def clear_global_around(self, reset_distance: float) -> None:
        x, y, _ = self.local_pose()
        self.global_costmap.clear_around(x, y, float(reset_distance))

    def clear_global_except(self, reset_distance: float) -> None:
        x, y, _ = self.local_pose()
        self.global_costmap.clear_except_region(x, y, float(reset_distance))

    def clear_local_around(self, reset_distance: float) -> None:
        self._catch_up_local()
        x, y, _ = self.local_pose()
        self._active_local().clear_around(x, y, float(reset_distance))

    def clear_local_except(self, reset_distance: float) -> None:
        self._catch_up_local()
        x, y, _ = self.local_pose()
        self._active_local().clear_except_region(x, y, float(reset_distance))

    def set_map(self, grid: OccupancyMap) -> None:
        """LoadMap: new static layer; the local costmap re-anchors. Localization is kept (same frame)."""
        self.grid = grid
        self.global_costmap.set_map(grid)
        self.local_costmap.set_static(self.global_costmap)
        if isinstance(self.localizer, Amcl):
            self.localizer.set_map(grid)

    # --- localization --------------------------------------------------------------------------------
    def set_initial_pose(self, x: float, y: float, yaw: float, cov: Any = None) -> None:
        """What a PoseWithCovarianceStamped on 'initialpose' does: (re)seed the localizer at the current odometry.
        `cov` is the 3x3 (x, y, yaw) covariance of the message (None: amcl's initial_cov_* parameters)."""
        self.localizer.set_initial_pose(x, y, yaw, self.odom_pose(), self.now, cov=cov)
        self._relocalized()

    def global_localization(self) -> None:
        """reinitialize_global_localization: particles over all free space (AMCL only)."""
        if not isinstance(self.localizer, Amcl):
            raise ValueError(f"global localization needs amcl, this simulator runs {self.localization} localization")
        self.localizer.global_localization(self.odom_pose(), self.now)
        self._relocalized()

    def request_nomotion_update(self) -> bool:
        """request_nomotion_update: a filter update on the next scan without motion (False when not AMCL)."""
        if not isinstance(self.localizer, Amcl):
            return False
        self.localizer.request_nomotion_update()
        self._last_scan_look = -math.inf
        return True

    def _relocalized(self) -> None:
        self.local_costmap.clear()  # its marks were in the old map frame
        self._last_costmap = -math.inf
        self._last_scan_look = -math.inf

    def localize(self) -> bool:
        """Offer the current scan to the localizer at the lidar rate; True when the map pose was updated."""
        if self.robot is None or self.now - self._last_scan_look < SCAN_PERIOD - 1e-6:
            return False
        self._last_scan_look = self.now
        loc = self.localizer
        if isinstance(loc, Amcl) and not loc.wants_update(self.odom_pose()):
            return False  # do not ray-cast a scan nobody reads
        return bool(loc.update(self.odom_pose(), self.robot.scan(), self.now))

    # --- loop ----------------------------------------------------------------------------------------
    def step(self, now: float | None = None) -> None:
        """Advance to sim time `now` (default: robot.time). Safe to call every physics step: it runs the
        controller at controller_frequency and the costmap at its update_frequency."""
        if now is None:
            now = float(self.robot.time) if self.robot is not None else self.now
        self.now = float(now)
        self.ctx.now = self.now
        self.localize()
        period = self.params.controller_period
        if self.now - self._last_control < period - 1e-6:
            return
        self._last_control = self.now
        # only here, never on a read, so what a publisher, a viewer or a service call reads cannot change what the
        # robot later does; while idle, readers get a fresh view on a copy instead (current_local_costmap)
        if self.active:
            self._refresh_local_costmap()
        task = self.task
        if task is not None and not task.done:
            disabled = self._drive_disabled(task)
            if disabled:
                task.abort(task.UNKNOWN, disabled, self.now)
            else:
                task.step(self.ctx, self.now)
        if task is not None and task.done and self._finished is not task:
            # one zero command when a task ends, also when it was canceled from outside (ROS cancel callback)
            self._finished = task
            self.ctx.stop()

    # --- tasks ---------------------------------------------------------------------------------------
    def _start(self, task: _T) -> _T:
        if self.paused:
            return _rejected(task, task.UNKNOWN, PAUSED_MSG)
        disabled = self._drive_disabled(task)
        if disabled:  # the running task (if any) goes on: nothing was started in its place
            return _rejected(task, task.UNKNOWN, disabled)
        self.cancel()
        self.task = task
        self._last_control = -math.inf  # the new task acts on the next step
        self._last_costmap = -math.inf  # ... on a fresh local costmap
        return task

    def _drive_disabled(self, task: Task) -> str:
        """Why `task` cannot run now ('' when it can): it drives, and the base cannot until it is docked."""
        if not task.drives or self.robot is None:
            return ""
        return self.robot.drive_disabled()

    def cancel(self) -> None:
        """Cancel the running motion task (if any) and stop the robot."""
        if self.task is not None and not self.task.done:
            self.task.cancel()
            self.ctx.stop()

    @property
    def active(self) -> bool:
        return self.task is not None and not self.task.done

    # one line a task: each start_* takes its task's own arguments (typed), so they are written once, on the task
    start_navigate_to_pose = _starter(NavigateToPose)
    start_navigate_through_poses = _starter(NavigateThroughPoses)
    start_follow_waypoints = _starter(FollowWaypoints)
    start_follow_path = _starter(FollowPath)
    start_spin = _starter(Spin)
    start_backup = _starter(BackUp)
    start_drive_on_heading = _starter(DriveOnHeading)
    start_wait = _starter(Wait)
    start_assisted_teleop = _starter(AssistedTeleop)

    def teleop_velocity(self, v: float, w: float) -> bool:
        """cmd_vel_teleop: forwarded to a running assisted_teleop (False when none is running)."""
        if isinstance(self.task, AssistedTeleop) and not self.task.done:
            self.task.set_teleop_velocity(v, w, self.now)
            return True
        return False

    def preempt_teleop(self) -> bool:
        """preempt_teleop: ends a running assisted_teleop successfully."""
        if isinstance(self.task, AssistedTeleop) and not self.task.done:
            self.task.preempt()
            return True
        return False

    # --- lifecycle -----------------------------------------------------------------------------------
    def pause(self) -> None:
        """ManageLifecycleNodes PAUSE: stop and cancel motion; new tasks are rejected until resume()."""
        self.cancel()
        self.paused = True

    def resume(self) -> None:
        self.paused = False

    # --- services / planning -------------------------------------------------------------------------
    def _start_pose(self, start: Sequence[float] | None) -> Sequence[float]:
        if start is not None:
            return start
        pose = self.pose()
        if pose is None:
            raise NotLocalizedError()
        return pose

    def compute_path(self, start: Sequence[float] | None, goal: Sequence[float]) -> PlanResult:
        """ComputePathToPose from `start` (or the localized pose when None; NotLocalizedError without one)."""
        return self.planner.plan(self.planning_costmap(), self._start_pose(start), goal)

    def compute_path_through(self, start: Sequence[float] | None, goals: Sequence[Sequence[float]]) -> PlanResult:
        return self.planner.plan_through(self.planning_costmap(), self._start_pose(start), goals)

    def smooth(self, path: np.ndarray, max_duration: float = 2.0, check_for_collision: bool = False) -> SmoothResult:
        return smooth_path(
            np.asarray(path, dtype=float),
            self.global_costmap.costmap,
            max_duration=max_duration,
            check_for_collision=check_for_collision,
        )

    def is_path_valid(
        self, path: np.ndarray, max_cost: int = 254, consider_unknown_as_obstacle: bool = False
    ) -> tuple[bool, list[int]]:
        return is_path_valid(
            self.planning_costmap(), np.asarray(path, dtype=float), max_cost, consider_unknown_as_obstacle
        )

    @property
    def last_status(self) -> str | None:
        return self.task.status if self.task is not None else None

    def __repr__(self) -> str:
        state = "paused" if self.paused else (self.task.name if self.active and self.task else "idle")
        return f"NavigationCore({state}, localized={self.localizer.is_localized})"
