"""Simulation: the simulated TurtleBot 4 in its world, stepped at a fixed physics rate in sim time.

It wires the parts together (drive, collision, lidar, battery, dock actions, odometry) and owns the clock. All
randomness comes from one seed, split into independent streams for odometry and lidar noise, so the same seed
and the same sequence of calls give bit-identical runs. Nothing here sleeps or uses threads.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tb4.core.geometry import Pose2D, wrap_angle
from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import RobotParams, default_robot_params
from tb4.sim.battery import Battery, BatteryStatus
from tb4.sim.collision import CollisionChecker, DistanceField, circles_clearance
from tb4.sim.create3 import BATTERY_EMPTY, Create3Base
from tb4.sim.dock import (
    DockAction,
    DockActionState,
    UndockAction,
    dock_visible,
    is_docked,
)
from tb4.sim.goal_state import FAILED
from tb4.sim.lidar import LaserScan, Lidar
from tb4.sim.motion import build_drive_goal
from tb4.sim.obstacles import Obstacle, PathMover, static_mask
from tb4.sim.robot import DiffDrive, Odometry, OdometryIntegrator, check_command

if TYPE_CHECKING:
    from tb4.sim.world import World

__all__ = [
    "Odometry",
    "LaserScan",
    "BatteryStatus",
    "HazardEvent",
    "DockActionState",
    "Simulation",
]


_DOCKING = ("dock", "undock")  # actions the backup limit does not apply to: the dock area is known floor


@dataclass(frozen=True)
class HazardEvent:
    """A bumper press: recorded when the robot comes into contact (not again while it stays in contact)."""

    time: float
    kind: str
    x: float
    y: float


def _pose3(value: Any, name: str) -> tuple[float, float, float]:
    try:
        x, y, yaw = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (x, y, yaw), got {value!r}") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return (x, y, wrap_angle(yaw))


class Simulation:
    """The robot in a static map with extra (possibly moving) obstacles; see docs/architecture.md."""

    def __init__(
        self,
        grid: OccupancyMap,
        dock: tuple[float, float, float],
        start: tuple[float, float, float],
        obstacles: Sequence[Obstacle] = (),
        params: RobotParams | None = None,
        seed: int | np.random.SeedSequence = 0,
        battery_level: float = 1.0,
        physics_dt: float = 0.01,
        odom_noise: bool = False,
        lidar_noise: bool = False,
        static_mask: np.ndarray | None = None,
        cliffs: Sequence[object] = (),
        docks: Sequence[tuple[float, float, float]] = (),
        distance_field: DistanceField | None = None,
    ) -> None:
        if not (isinstance(physics_dt, (int, float)) and 0.0 < physics_dt <= 1.0):
            raise ValueError(f"physics_dt must be within (0, 1] s, got {physics_dt!r}")
        self.params = params if params is not None else default_robot_params()
        self.physics_dt = float(physics_dt)
        self.dock_pose = _pose3(dock, "dock")  # the dock this robot charges on (the last one it docked at)
        # every dock in the world (a fleet shares them); a dock goal docks at the nearest visible one
        self.docks = tuple(_pose3(d, "docks") for d in docks) or (self.dock_pose,)
        # (x, y, radius) of the other robots in this world, set by tb4.sim.fleet.Fleet before each step: the lidar
        # sees them and the drive collides with them like moving obstacles
        self.peers: list[tuple[float, float, float]] = []
        # which robot sits on a dock pose ("" if none): set by the fleet, so a busy dock refuses a dock goal
        self.dock_occupant: Callable[[tuple[float, float, float]], str] = lambda _dock: ""
        self.fleet_size = 1  # robots in this world (a Fleet sets it): a map switch would split a shared world
        self.x, self.y, self.yaw = _pose3(start, "start")
        self.lidar_noise = lidar_noise
        # independent streams, so turning lidar noise on does not change the odometry drift (and vice versa); a
        # fleet hands each robot its own SeedSequence
        root = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        odom_seq, lidar_seq, spare_seq = root.spawn(3)
        self.rng = np.random.default_rng(spare_seq)  # for callers that want randomness tied to this run's seed
        self._static_obstacles = [o for o in obstacles if not o.moving]
        self._moving = [PathMover(o) for o in obstacles if o.moving]
        self._moving_radius = [
            m.obstacle.radius if m.obstacle.shape == "circle" else 0.5 * math.hypot(*m.obstacle.size)
            for m in self._moving
        ]
        self._circles_at: tuple[float, list[tuple[float, float, float]]] = (math.nan, [])
        self.grid = grid
        if distance_field is None:  # a fleet builds it once for all its robots (it is the map's size in floats)
            mask = static_mask if static_mask is not None else self._mask_for(grid)
            distance_field = DistanceField.from_mask(grid, mask)
        self.field = distance_field
        self._checker = CollisionChecker(self.field, self.params.drive.radius, self.params.drive.collision_min_step)
        self._lidar = Lidar(self.params.lidar, self.field, lidar_seq)
        self._drive = DiffDrive(self.params.drive)
        self._odom = OdometryIntegrator(self.params.odometry, np.random.default_rng(odom_seq) if odom_noise else None)
        self._battery = Battery(self.params.battery, battery_level)
        self._steps = 0
        self._hazards: list[HazardEvent] = []
        self._in_contact = False
        self._action: DockAction | UndockAction | None = None
        self._scan_key: tuple[int, int] | None = None
        self._scan: LaserScan | None = None
        self._still = 0  # still steps in a row (see _still_steps)
        self._movers_far_until = 0.0  # no moving obstacle can be near before this step (see _movers_near)
        self._version = 0  # bumped by teleports and map switches (scan cache key)
        docked = self.is_docked()
        self._battery.update(0.0, docked=docked)
        self.base = Create3Base(self.params, cliffs)  # safety, hazards, sensors and UI of the Create 3
        self._report_battery(docked)  # a robot started off its dock with a flat pack cannot drive

    @classmethod
    def from_world(cls, world: World, **kwargs: Any) -> Simulation:
        """A simulation of a tb4.sim.world.World (its map, static obstacles, moving obstacles, dock and start)."""
        kwargs.setdefault("obstacles", world.obstacles)
        kwargs.setdefault("static_mask", world.static_obstacle_mask())
        kwargs.setdefault("cliffs", getattr(world, "cliffs", ()))  # optional in the world contract
        return cls(world.map, world.dock, world.start, **kwargs)

    # ------------------------------------------------------------------ clock and stepping
    @property
    def time(self) -> float:
        """Sim seconds since start (an exact multiple of physics_dt: no accumulated rounding)."""
        return self._steps * self.physics_dt

    @property
    def steps(self) -> int:
        return self._steps

    def step(self, n: int = 1) -> None:
        """Advance n fixed physics steps. Steps in which a still robot stays still (hours on the dock, charging)
        are taken together, with the same result to the last bit as one at a time."""
        remaining = int(n)
        while remaining > 0:
            still = self._still_steps(remaining)
            if still:
                self._rest(still)
                remaining -= still
            else:
                self._step_once()
                remaining -= 1

    def still_steps(self, n: int) -> int:
        """How many of the next n physics steps (0 to n) change nothing but the clock and the battery (see
        _still_steps): the simulator loop takes that many at once while nothing else happens."""
        return self._still_steps(n)

    def resting(self) -> bool:
        """Whether the robot waits for a command: at rest with nothing driving it (`_at_rest`) and not charging
        towards full on a dock. A peer or a moving obstacle near does not count: it does not drive this robot."""
        battery = self._battery
        return self._at_rest() and not (battery.charging and not battery.full)

    def _at_rest(self) -> bool:
        """The last two steps left the robot still, and nothing drives it: no command, action or timed input."""
        drive = self._drive
        return not (
            self._still < 2
            or self._action is not None
            or drive.v
            or drive.w
            or drive.target_v
            or drive.target_w
            or not self._odom.at_rest()
            or not self.base.at_rest()
        )

    def _still_steps(self, n: int) -> int:
        """How many of the next n steps (0 to n) can change nothing but the clock, the battery and the last bits of
        the wrapped headings: the robot is at rest (`_at_rest`), no peer is near, no moving obstacle can reach
        the bumper within them, and the pack does not run flat or start charging from flat within them (that step
        stops the motors, or starts them again, at its own sim time: it is taken alone)."""
        if self.peers or not self._at_rest():
            return 0
        steps = min(n, self._movers_away_for(0.0))
        battery = self._battery
        if battery.empty:
            return 0 if self.base.battery_empty and self.is_docked() else int(steps)
        left = battery.rest_steps_before_empty(self.physics_dt)
        if left < steps and not self.is_docked():
            steps = left
        return int(steps)

    def _movers_away_for(self, own_speed: float) -> float:
        """Steps from now during which no moving obstacle can come within the bumper's reach, plus one minimum
        collision sub-step and one step at full speed, of this robot moving at up to `own_speed` m/s: their speeds
        plus its bound the approach. 0 when one may already be that close (or moves along no path with a speed).
        Beyond that reach an obstacle changes neither a step's collision sub-steps nor the bumper."""
        if not self._moving:
            return math.inf
        steps = math.inf
        checker = self._checker
        reach = checker.radius + checker.min_step + self.params.drive.max_linear_speed * self.physics_dt
        for mover, (cx, cy, r) in zip(self._moving, self.moving_circles(), strict=True):
            if not mover.fast:
                return 0  # no speed to bound its travel by
            gap = math.hypot(cx - self.x, cy - self.y) - r - reach
            if gap <= 0.0:
                return 0
            closing = (mover.speed + own_speed) * self.physics_dt
            if closing > 0.0:
                steps = min(steps, gap / closing)
        return steps if math.isinf(steps) else math.floor(steps)

    def _movers_near(self) -> bool:
        """Whether this step must take the moving obstacles into account. While every one is far, the step's
        collision check and bumper give the same result without them (their clearance exceeds any step), so
        their positions are not computed until the soonest one could have come near."""
        if self._steps < self._movers_far_until:
            return False
        away = self._movers_away_for(self.params.drive.max_linear_speed)
        self._movers_far_until = self._steps + away
        return away == 0

    def _moved_by_hand(self) -> None:
        """A teleport or a map switch: the still steps and the movers' distance start again from the new state."""
        self._still = 0
        self._movers_far_until = 0.0

    def _rest(self, steps: int) -> None:
        """`steps` physics steps of a still robot (see _still_steps): what _step_once would do, at once."""
        dt = self.physics_dt
        docked = is_docked((self.x, self.y, self.yaw), self.dock_pose, self.params.dock)
        self._battery.rest(dt, steps, docked)
        self._odom.rest(steps)
        self._steps += steps
        self._report_battery(docked)
        self.base.rest(self.time, steps)

    def _step_once(self) -> None:
        dt = self.physics_dt
        t = self._steps * dt
        drive = self._drive
        action = self._action
        if action is not None and action.state.done:  # canceled from outside
            self._end_action()
            action = None
        if action is not None:
            _, _, vc, wc = check_command(*action.command((self.x, self.y, self.yaw), t), self.params.drive)
            drive.set_target(vc, wc, t)
        v_prev = drive.v
        v, w = drive.update(t, dt, enabled=not self._battery.empty)
        kind = action.state.kind if action is not None else ""
        v, w, stopped = self.base.gate(self, v, w, builtin=bool(kind), exempt=kind in _DOCKING)
        if stopped:
            drive.halt()
        circles = self.moving_circles((self._steps + 1) * dt) if self._moving and self._movers_near() else ()
        peers = self.peers
        if peers:
            circles = [*circles, *peers]
        before = (self.x, self.y, self.yaw)
        x, y, yaw, blocked = self._checker.move(self.x, self.y, self.yaw, v, w, dt, circles)
        if blocked:
            drive.halt()
        pressed = blocked or (bool(circles) and circles_clearance(x, y, circles) < self._checker.radius)
        # another robot that drove into this one stopped at the contact distance: the bumper feels it too
        reach = self._checker.radius + self._checker.min_step
        pressed = pressed or (bool(peers) and circles_clearance(x, y, peers) < reach)
        if pressed and not self._in_contact:
            self._hazards.append(HazardEvent((self._steps + 1) * dt, "bump", x, y))
        # the bumper stays pressed until the robot has backed off (no new event while it creeps on the wall)
        self._in_contact = pressed or (self._in_contact and self._checker.touching(x, y, circles))
        # still steps in a row: after two, every reading is at its fixed point (an acceleration is a difference of
        # two steps' speeds) and the next ones may be taken together (step), until something drives, moves or lifts it
        still = (x, y, yaw) == before and v == 0.0 and w == 0.0 and not (pressed or stopped or self._in_contact)
        self._still = self._still + 1 if still else 0
        self.x, self.y, self.yaw = x, y, yaw
        # wheel slip for the odometry: acceleration, and wheels still turning for the step a bump stopped
        self._odom.update(before, (x, y, yaw), dt, accel=(v - v_prev) / dt, spin=v * dt if blocked else 0.0)
        self._steps += 1
        docked = is_docked((x, y, yaw), self.dock_pose, self.params.dock)
        self._battery.update(dt, v, w, docked)
        self._report_battery(docked)  # run flat: the action ended (stop_motion), and the gate holds the wheels
        abort = self.base.after_move(self, before, (self.x, self.y, self.yaw), v, w, dt, blocked, kind in _DOCKING)
        if action is not None and (abort or stopped) and not isinstance(action, (DockAction, UndockAction)):
            action.abort(abort or stopped)  # a drive goal ends on a hazard, as on a Create 3
        if action is not None:
            pose = (x, y, yaw)
            action.update(pose, self.time, blocked)
            action.state.sees_dock = dock_visible(pose, self.dock_pose, self.params.dock)
            action.state.is_docked = docked
            if action.state.done:
                self._end_action()

    def _end_action(self) -> None:
        self._action = None
        self._drive.stop()

    def _report_battery(self, docked: bool) -> None:
        """Tell the base what the pack reads; when it has just run flat off the dock, every action ends (the dock
        ones too) and the wheels stop at once."""
        battery = self._battery
        if self.base.set_battery(battery.empty and not docked, battery.low, self.time):
            self.stop_motion(BATTERY_EMPTY)

    # ------------------------------------------------------------------ commands
    def set_velocity_command(self, v: float, w: float) -> tuple[bool, str]:
        """Accept (clamped) or reject a cmd_vel; it holds for command_timeout seconds of sim time."""
        ok, reason, vc, wc = check_command(v, w, self.params.drive)
        if not ok:
            return (False, reason)
        if self._action is not None and not self._action.state.done:
            return (False, f"ignored: {self._action.state.kind} action running")
        refusal = self.base.refuse_motion()
        if refusal:
            return (False, f"ignored: {refusal}")
        self._drive.set_target(vc, wc, self._steps * self.physics_dt)
        return (True, reason)

    def drive_disabled(self) -> str:
        """Why the base cannot drive until the robot is put on its dock: a flat battery, or robot_power.

        Navigation ends its goals on it at once; passing refusals (e-stop, a lift) it rides out, as Nav2 does.

        Returns:
            The reason, or '' when the base can drive.
        """
        base = self.base
        if base.battery_empty:
            return BATTERY_EMPTY
        if not base.powered:
            return base.refuse_motion()
        return ""

    def set_pose(self, x: float, y: float, yaw: float) -> None:
        """Teleport (ground truth only: odometry does not jump, as on a real robot); wheels stop."""
        self.x, self.y, self.yaw = _pose3((x, y, yaw), "pose")
        self._drive.halt()
        self._checker.reset()
        self._in_contact = False
        self._version += 1
        self._moved_by_hand()

    def set_grid(self, grid: OccupancyMap) -> None:
        """Switch to another map (LoadMap); static obstacles are rasterized onto it. Refused in a fleet, whose
        robots share one world."""
        if self.fleet_size > 1:
            raise ValueError(f"the {self.fleet_size} robots of this simulator share one world: its map cannot change")
        self.grid = grid
        self.field = DistanceField.from_mask(grid, self._mask_for(grid))
        self._checker.reset(self.field)
        self._lidar.set_field(self.field)
        self._version += 1
        self._moved_by_hand()

    def _mask_for(self, grid: OccupancyMap) -> np.ndarray:
        return static_mask(grid, self._static_obstacles)

    # ------------------------------------------------------------------ dock actions
    def start_dock(self) -> DockActionState:
        """Dock goal at the nearest visible dock; rejected (status failed) while the robot cannot drive
        (base.refuse_motion), when docked, when no dock is visible, when another robot occupies that dock, or
        while busy."""
        target = self._visible_dock()
        sees = target is not None
        state = DockActionState("dock", sees_dock=sees)
        state.is_docked = self.is_docked()
        occupant = self.dock_occupant(target) if target is not None else ""
        refusal = self.base.refuse_motion()
        if refusal:
            state.finish(FAILED, f"rejected: {refusal}")
        elif self._action is not None and not self._action.state.done:
            state.finish(FAILED, f"rejected: {self._action.state.kind} action already running")
        elif state.is_docked:
            state.finish(FAILED, "rejected: already docked")
        elif target is None:
            state.finish(FAILED, "rejected: dock not visible")
        elif occupant:
            state.finish(FAILED, f"rejected: dock occupied by {occupant}")
        else:
            self.dock_pose = target
            self._action = DockAction(self.dock_pose, self.params.dock, self.time, state)
        return state

    def start_undock(self) -> DockActionState:
        """Undock goal: reverse 0.4 m then turn 180 deg; rejected while the robot cannot drive, when not docked
        or while busy."""
        state = DockActionState("undock", sees_dock=self.dock_visible())
        state.is_docked = self.is_docked()
        refusal = self.base.refuse_motion()
        if refusal:
            state.finish(FAILED, f"rejected: {refusal}")
        elif self._action is not None and not self._action.state.done:
            state.finish(FAILED, f"rejected: {self._action.state.kind} action already running")
        elif not state.is_docked:
            state.finish(FAILED, "rejected: not docked")
        else:
            self._action = UndockAction((self.x, self.y, self.yaw), self.params.dock, self.time, state)
        return state

    def start_motion(self, make: Any) -> Any:
        """Start a Create 3 drive goal built by `make()` (raises ValueError for a bad goal or while the robot
        cannot move); it preempts any running action, which ends aborted."""
        refusal = self.base.refuse_motion()
        if refusal:
            raise ValueError(f"goal refused: {refusal}")
        motion = make()
        running = self._action
        if running is not None and not running.state.done:
            running.state.finish(FAILED, f"preempted by {motion.state.kind}")
        self._action = motion
        return motion.state

    def start_drive_goal(self, action: str, *fields: Any) -> Any:
        """Start a Create 3 drive goal from its action's name and its goal's fields as plain values (see
        tb4.sim.motion.build_drive_goal); as `start_motion`."""

        def odom() -> tuple[float, float, float]:
            o = self.odometry()
            return (o.x, o.y, o.yaw)

        side = int(fields[0]) if action == "wall_follow" and fields else 0
        return self.start_motion(
            lambda: build_drive_goal(
                action,
                odom,
                self.params.drive,
                fields,
                self.time,
                lambda: self.base.side_ranges(self, side),
                lambda: self.in_contact,
            )
        )

    def stop_motion(self, reason: str) -> None:
        """End any running action (it is aborted with `reason`) and stop the wheels at once."""
        if self._action is not None and not self._action.state.done:
            self._action.state.finish(FAILED, reason)
        self._drive.halt()
        self._drive.stop()

    def kidnap(self, x: float, y: float, yaw: float) -> None:
        """Lift the robot and put it down at (x, y, yaw) (map frame) after a moment. Odometry keeps its position
        (nothing rolled) but turns with the heading change, which the Create 3's gyro sees."""
        pose = _pose3((x, y, yaw), "kidnap pose")
        clear = self.clearance_at(pose[0], pose[1])
        if clear < self.params.drive.radius:
            raise ValueError(f"cannot put the robot down at ({pose[0]:g}, {pose[1]:g}): no room there")
        if self._action is not None and not self._action.state.done:
            self._action.state.finish(FAILED, "the robot was lifted")
        self._drive.halt()
        self._drive.stop()
        self.base.kidnap(pose, self.time)

    def reset_odometry(self, x: float, y: float, yaw: float) -> None:
        """reset_pose: odometry reads (x, y, yaw) from now on; the robot does not move."""
        self._odom.x, self._odom.y, self._odom.yaw = _pose3((x, y, yaw), "pose")

    @property
    def has_moving_obstacles(self) -> bool:
        return bool(self._moving)

    def turn_odometry(self, angle: float) -> None:
        """The heading odometry reads turns by `angle` without any travel (the gyro of a lifted, turned robot)."""
        self._odom.yaw = wrap_angle(self._odom.yaw + angle)

    def clearance_at(self, x: float, y: float) -> float:
        """Distance from (x, y) to the nearest surface: walls, static and moving obstacles."""
        c = self.field.clearance(x, y)
        if self.peers:
            c = min(c, circles_clearance(x, y, self.peers))
        return min(c, circles_clearance(x, y, self.moving_circles())) if self._moving else c

    # ------------------------------------------------------------------ readings
    def pose(self) -> Pose2D:
        """Ground truth in the map frame."""
        return Pose2D(self.x, self.y, self.yaw)

    def velocity(self) -> tuple[float, float]:
        """Actual (v, w) of the base after ramps and bumps."""
        return (self._drive.v, self._drive.w)

    def odometry(self) -> Odometry:
        return self._odom.reading()

    def moving_circles(self, t: float | None = None) -> list[tuple[float, float, float]]:
        """(x, y, radius) of the moving obstacles at sim time t (default: now)."""
        t = self.time if t is None else t
        if self._circles_at[0] != t:
            out = []
            for mover, r in zip(self._moving, self._moving_radius, strict=True):
                px, py = mover.position(t)
                out.append((px, py, r))
            self._circles_at = (t, out)
        return list(self._circles_at[1])

    def scan(self) -> LaserScan:
        """Lidar scan at the current pose and time (computed once per step, then cached)."""
        key = (self._steps, self._version)
        if self._scan is None or self._scan_key != key:
            circles = self.moving_circles() if self._moving else []
            if self.peers:
                circles = [*circles, *self.peers]
            self._scan = self._lidar.scan(
                self.x, self.y, self.yaw, self.time, circles, noise=self.lidar_noise, step=self._steps
            )
            self._scan_key = key
        return self._scan

    def battery(self) -> BatteryStatus:
        return self._battery.status()

    def dock_visible(self) -> bool:
        """Whether any dock is in view (this robot's own dock, or in a fleet any shared one)."""
        return self._visible_dock() is not None

    def _visible_dock(self) -> tuple[float, float, float] | None:
        """The nearest visible dock (None: none in view); a single robot knows only its own."""
        pose, p = (self.x, self.y, self.yaw), self.params.dock
        if len(self.docks) == 1:
            return self.dock_pose if dock_visible(pose, self.dock_pose, p) else None
        seen = [d for d in self.docks if dock_visible(pose, d, p)]
        return min(seen, key=lambda d: math.hypot(d[0] - self.x, d[1] - self.y)) if seen else None

    def is_docked(self) -> bool:
        return is_docked((self.x, self.y, self.yaw), self.dock_pose, self.params.dock)

    @property
    def lidar(self) -> Lidar:
        """The ray caster (beam geometry and params; ranges() at any pose without touching the scan cache)."""
        return self._lidar

    @property
    def in_contact(self) -> bool:
        """True while the bumper is pressed."""
        return self._in_contact

    def pop_hazards(self) -> list[HazardEvent]:
        out, self._hazards = self._hazards, []
        return out
