"""What the viewer knows about one robot: the newest value of each topic, and snapshots of it for the page.

The ROS bridge writes plain values here (never messages, no rclpy), the web server reads bounded-rate snapshots.
Everything is a latest-value cache or a bounded ring (tracking.py), so a fast simulator or a slow browser never
grows memory. Grids go to the page as indexed PNG images (grid_image.py), encoded lazily, once per version.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tb4.core import robot_params
from tb4.core.geometry import compose
from tb4.viewer.grid_image import COSTMAP_PALETTE, MAP_PALETTE, Grid, grid_png
from tb4.viewer.tracking import RealTimeFactor, TaskTracker, Trail

__all__ = ["LAYERS", "ClientCursor", "ViewerState", "PARTICLE_POINTS", "PLAN_POINTS"]

#: Grid layers the page can draw, with the least wall time between two sends of a new version to one page.
LAYERS: dict[str, float] = {"map": 0.0, "global_costmap": 1.0, "local_costmap": 0.2}

PARTICLE_POINTS = 600  # particle cloud points sent per state message, at most
PLAN_POINTS = 400  # most points of a plan sent to the page
RELOCALIZED = 0.3  # m or rad: a map->odom change this large (a new initial pose) restarts the trail


@dataclass
class ClientCursor:
    """What one page already has, so each snapshot sends it only what changed."""

    layer_versions: dict[str, int] = field(default_factory=dict)
    layer_sent_at: dict[str, float] = field(default_factory=dict)
    plan_version: int = -1
    trail_epoch: int = -1
    trail_seq: int = 0
    notice_seq: int = 0
    world_version: int = -1


def _r(value: float, digits: int = 3) -> float | None:
    return round(float(value), digits) if math.isfinite(value) else None


class ViewerState:
    """Thread-safe latest values for one robot namespace. Writers: the ROS bridge; readers: the web server."""

    def __init__(
        self, namespace: str = "", robot_radius: float | None = None, clock: Callable[[], float] = time.monotonic
    ):
        self.namespace = namespace
        self.robot_radius = robot_radius if robot_radius is not None else robot_params.robot_radius()
        self.clock = clock
        self._lock = threading.Lock()
        self._layers: dict[str, tuple[int, Grid | None]] = {name: (0, None) for name in LAYERS}
        self._png_cache: dict[str, tuple[int, bytes]] = {}
        self._png_lock = threading.Lock()
        self.odom_base: tuple[float, float, float] | None = None
        self.truth: tuple[float, float, float] | None = None  # a fleet robot's true pose (simulator), unlocalized
        self.map_odom: tuple[float, float, float] | None = None
        self.velocity: tuple[float, float] = (0.0, 0.0)
        self.scan: dict[str, Any] | None = None
        self.plan: np.ndarray | None = None
        self.plan_frame = "map"
        self.plan_version = 0
        self.trail = Trail()
        self.amcl: tuple[float, float, float] | None = None
        self.particles: list[float] = []  # flat x, y of AMCL's particle cloud
        self.battery: dict[str, Any] | None = None
        self.dock: dict[str, bool] | None = None
        self.create3: dict[str, Any] = {}  # light ring, buttons held, hazards (viewer/create3_panel.py)
        self.sim_time: float | None = None
        self.rtf = RealTimeFactor(clock=clock)
        self.tasks = TaskTracker(clock=clock)
        self.goal: dict[str, Any] | None = None
        self.waypoints: list[dict[str, Any]] = []
        self.world: dict[str, Any] | None = None
        self.world_version = 0
        self.fleet: tuple[str, ...] = ()  # the robots sharing this robot's world (its `fleet` topic), in order
        self._notices: deque[tuple[int, str, str]] = deque(maxlen=50)
        self._notice_seq = 0

    # --- writers (ROS thread) -------------------------------------------------------------------------------
    def set_layer(self, name: str, grid: Grid) -> None:
        if name not in LAYERS:
            raise ValueError(f"unknown layer {name!r}")
        with self._lock:
            version, old = self._layers[name]
            if old is not None and old.signature() == grid.signature() and np.array_equal(old.data, grid.data):
                return  # republished unchanged (the local costmap is, twice a second): nothing new to send
            self._layers[name] = (version + 1, grid)

    def layer(self, name: str) -> tuple[int, Grid | None]:
        with self._lock:
            return self._layers[name]

    def set_odom_base(self, pose: tuple[float, float, float]) -> None:
        with self._lock:
            self.odom_base = pose
            robot = self._robot_pose_locked()
            if robot is not None and self._frame_locked() != "truth":  # set_truth adds those
                self.trail.add(robot[0], robot[1])

    def set_truth(self, pose: tuple[float, float, float]) -> None:
        """The simulator's true pose: where a fleet robot is drawn until it is localized (each robot's odom frame
        starts where that robot started, so odom drawn as the map would stack the fleet at the origin)."""
        with self._lock:
            self.truth = pose
            if self.map_odom is None:
                self.trail.add(pose[0], pose[1])

    def set_map_odom(self, pose: tuple[float, float, float]) -> None:
        with self._lock:
            old = self.map_odom
            if old is not None and (
                math.hypot(pose[0] - old[0], pose[1] - old[1]) > RELOCALIZED
                or abs(math.remainder(pose[2] - old[2], 2 * math.pi)) > RELOCALIZED
            ):
                self.trail.clear()  # a new initial pose: the trail so far was drawn in a frame now known wrong
            self.map_odom = pose

    def set_velocity(self, v: float, w: float) -> None:
        self.velocity = (float(v), float(w))

    def set_scan(self, ranges: np.ndarray, angle_min: float, angle_increment: float, rmin: float, rmax: float) -> None:
        scan = {"ranges": np.asarray(ranges, dtype=np.float32), "angle_min": angle_min, "inc": angle_increment}
        scan.update(range_min=rmin, range_max=rmax)
        self.scan = scan

    def set_plan(self, points: np.ndarray, frame: str = "map") -> None:
        with self._lock:
            self.plan = np.asarray(points, dtype=np.float64).reshape(-1, 3)
            self.plan_frame = frame or "map"
            self.plan_version += 1
            if len(self.plan):
                x, y, yaw = (float(v) for v in self.plan[-1])
                self._plan_end_locked(x, y, yaw)

    def _plan_end_locked(self, x: float, y: float, yaw: float) -> None:
        """Without a known goal (a real Nav2 announces none), the plan's end is the goal."""
        known = ([self.goal] if self.goal and self.goal["source"] != "plan" else []) + self.waypoints
        if any(math.hypot(p["x"] - x, p["y"] - y) < 0.5 for p in known):
            return  # a plan towards a goal we know ends within its tolerance: keep the exact pose
        self.goal = {"x": _r(x), "y": _r(y), "yaw": _r(yaw), "source": "plan"}
        self.waypoints = []

    def set_goal(self, x: float, y: float, yaw: float, source: str) -> None:
        """A goal the page sent ("page") or someone announced."""
        with self._lock:
            self.goal = {"x": _r(x), "y": _r(y), "yaw": _r(yaw), "source": source}

    def set_goals(self, poses: Sequence[tuple[float, float, float]]) -> None:
        """Announced goal poses (the simulator's `goals` topic): the last is the goal, all are waypoints if several."""
        poses = [p for p in poses if all(math.isfinite(v) for v in p)][:200]
        with self._lock:
            if not poses:
                return
            x, y, yaw = poses[-1]
            self.goal = {"x": _r(x), "y": _r(y), "yaw": _r(yaw), "source": "goals"}
            self.waypoints = (
                [{"x": _r(px), "y": _r(py), "yaw": _r(pyaw), "status": 0} for px, py, pyaw in poses]
                if len(poses) > 1
                else []
            )

    def set_waypoint_statuses(self, waypoints: list[dict[str, Any]]) -> None:
        """Waypoints with their WaypointStatus (navigate_through_poses feedback)."""
        with self._lock:
            self.waypoints = waypoints[:200]

    def set_amcl(self, pose: tuple[float, float, float]) -> None:
        self.amcl = pose

    def set_particles(self, points: np.ndarray) -> None:
        """AMCL's particle cloud (x, y), thinned to PARTICLE_POINTS for the browser; non-finite ones dropped."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        pts = pts[np.isfinite(pts).all(axis=1)]
        step = max(1, math.ceil(len(pts) / PARTICLE_POINTS))
        self.particles = np.round(pts[::step], 3).ravel().tolist()

    def set_battery(self, battery: dict[str, Any]) -> None:
        self.battery = battery

    def set_create3(self, key: str, value: Any) -> None:
        self.create3 = {**self.create3, key: value}  # replaced, never mutated: snapshots share it safely

    def set_dock(self, is_docked: bool, dock_visible: bool) -> None:
        self.dock = {"is_docked": bool(is_docked), "dock_visible": bool(dock_visible)}

    def set_sim_time(self, seconds: float) -> None:
        if math.isfinite(seconds):
            self.sim_time = seconds
            self.rtf.add(seconds)

    def set_world(self, world: dict[str, Any] | None) -> None:
        with self._lock:
            if world != self.world:
                self.world = world
                self.world_version += 1

    def set_fleet(self, namespaces: tuple[str, ...]) -> None:
        with self._lock:
            self._set_fleet_locked(namespaces)

    def join_fleet(self, namespaces: tuple[str, ...]) -> None:
        """Another robot's fleet names this one: a fleet robot before its own (latched) `fleet` message arrives,
        so never drawn from its odom frame as if it were the map (the fleet stacked on the first dock)."""
        with self._lock:
            if not self.fleet:
                self._set_fleet_locked(namespaces)

    def _set_fleet_locked(self, namespaces: tuple[str, ...]) -> None:
        if namespaces and not self.fleet and self.map_odom is None:
            self.trail.clear()  # drawn from odom so far; a fleet robot is drawn from its true pose from now on
        self.fleet = tuple(namespaces)[:100]

    def notice(self, level: str, text: str) -> None:
        """A message for every page (goal accepted, aborted with a reason, ...)."""
        with self._lock:
            self._notice_seq += 1
            self._notices.append((self._notice_seq, level, text[:300]))

    # --- readers -------------------------------------------------------------------------------------------
    def _robot_pose_locked(self) -> tuple[float, float, float] | None:
        if self.map_odom is None and self.fleet:
            return self.truth  # a fleet robot not localized yet: where the simulator says it is (labelled so)
        if self.odom_base is None:
            return None
        if self.map_odom is None:
            return self.odom_base  # not localized yet: draw odom as if it were the map (labelled so on the page)
        return compose(self.map_odom, self.odom_base)

    def _frame_locked(self) -> str:
        if self.map_odom is not None:
            return "map"
        return "truth" if self.fleet else "odom"

    def robot_pose(self) -> tuple[float, float, float] | None:
        with self._lock:
            return self._robot_pose_locked()

    def layer_png(self, name: str) -> tuple[int, Grid, bytes] | None:
        """(version, grid, PNG) of a layer, encoding at most once per version (callers may be several pages)."""
        version, grid = self.layer(name)
        if grid is None:
            return None
        with self._png_lock:
            cached = self._png_cache.get(name)
            if cached is None or cached[0] != version:
                palette = MAP_PALETTE if name == "map" else COSTMAP_PALETTE
                cached = (version, grid_png(grid, palette))
                self._png_cache[name] = cached
        return version, grid, cached[1]

    def layers_due(self, cursor: ClientCursor, wanted: Sequence[str], now: float | None = None) -> list[str]:
        """Layers with a version the page lacks and whose minimum resend interval has passed."""
        now = self.clock() if now is None else now
        due = []
        for name in wanted:
            version, grid = self.layer(name)
            if grid is None or cursor.layer_versions.get(name) == version:
                continue
            if now - cursor.layer_sent_at.get(name, -math.inf) < LAYERS[name]:
                continue
            due.append(name)
        return due

    def _scan_points(self, pose: tuple[float, float, float]) -> list[float] | None:
        scan = self.scan
        if scan is None:
            return None
        ranges = scan["ranges"]
        angles = scan["angle_min"] + scan["inc"] * np.arange(len(ranges)) + pose[2]
        ok = np.isfinite(ranges) & (ranges >= scan["range_min"]) & (ranges < scan["range_max"])
        xs = pose[0] + ranges[ok] * np.cos(angles[ok])
        ys = pose[1] + ranges[ok] * np.sin(angles[ok])
        return np.round(np.column_stack([xs, ys]).ravel(), 2).tolist()

    def _plan_points(self, plan: np.ndarray) -> list[float]:
        step = max(1, math.ceil(len(plan) / PLAN_POINTS))
        pts = plan[::step, :2]
        if len(plan) and step > 1:
            pts = np.vstack([pts, plan[-1:, :2]])
        return list(np.round(pts, 3).ravel().tolist())

    def _pose_dict(self, pose: tuple[float, float, float], frame: str) -> dict[str, Any]:
        return {
            "x": _r(pose[0]),
            "y": _r(pose[1]),
            "yaw": _r(pose[2]),
            "localized": frame == "map",
            "frame": frame,
            "radius": self.robot_radius,
        }

    def overview(self, cursor: ClientCursor) -> dict[str, Any]:
        """What the page draws of a fleet robot it is not commanding: where it is, its goal, plan, trail and task.
        Advances `cursor` past the plan and trail points it includes."""
        with self._lock:
            pose = self._robot_pose_locked()
            frame = self._frame_locked()
            plan = self.plan if self.plan_version != cursor.plan_version else None
            plan_version = self.plan_version
            goal = dict(self.goal) if self.goal else None
            reset, trail, seq = self.trail.since(cursor.trail_epoch, cursor.trail_seq)
            trail_epoch = self.trail.epoch
        task = self.tasks.current()
        msg: dict[str, Any] = {
            "namespace": self.namespace,
            "robot": self._pose_dict(pose, frame) if pose is not None else None,
            "goal": goal,
            "task": {"action": task["action"], "status": task["status"], "active": task["active"]} if task else None,
        }
        if plan is not None:
            msg["plan"] = self._plan_points(plan)
            cursor.plan_version = plan_version
        if reset or trail:
            msg["trail"] = {"reset": reset, "points": trail}
        cursor.trail_epoch, cursor.trail_seq = trail_epoch, seq
        return msg

    def snapshot(self, cursor: ClientCursor, wall: float | None = None) -> dict[str, Any]:
        """The page's next `state` message; advances `cursor` past what it includes."""
        with self._lock:
            pose = self._robot_pose_locked()
            frame = self._frame_locked()
            plan = self.plan if self.plan_version != cursor.plan_version else None
            plan_version, plan_frame = self.plan_version, self.plan_frame
            goal = dict(self.goal) if self.goal else None
            waypoints = list(self.waypoints)
            notices = [(s, lvl, txt) for s, lvl, txt in self._notices if s > cursor.notice_seq]
            world = self.world if self.world_version != cursor.world_version else None
            world_version = self.world_version
            layer_versions = {name: v for name, (v, g) in self._layers.items() if g is not None}
            reset, trail, seq = self.trail.since(cursor.trail_epoch, cursor.trail_seq)
            trail_epoch = self.trail.epoch
        msg: dict[str, Any] = {
            "type": "state",
            "namespace": self.namespace,
            "sim_time": _r(self.sim_time, 2) if self.sim_time is not None else None,
            "rtf": _r(rtf, 2) if (rtf := self.rtf.value(wall)) is not None else None,
            "robot": None,
            "scan": None,
            "battery": self.battery,
            "dock": self.dock,
            "create3": self.create3 or None,
            "task": self.tasks.current(),
            "goal": goal,
            "waypoints": waypoints,
            "amcl": None,
            "particles": self.particles,
            "layers": layer_versions,
        }
        if pose is not None:
            v, w = self.velocity
            msg["robot"] = {**self._pose_dict(pose, frame), "v": _r(v, 2), "w": _r(w, 2)}
            msg["scan"] = self._scan_points(pose)
        if self.amcl is not None:
            msg["amcl"] = {"x": _r(self.amcl[0]), "y": _r(self.amcl[1]), "yaw": _r(self.amcl[2])}
        if plan is not None:
            msg["plan"] = {"frame": plan_frame, "points": self._plan_points(plan)}
            cursor.plan_version = plan_version
        if reset or trail:
            msg["trail"] = {"reset": reset, "points": trail}
        cursor.trail_epoch, cursor.trail_seq = trail_epoch, seq
        if notices:
            msg["notices"] = [{"level": lvl, "text": txt} for _, lvl, txt in notices]
            cursor.notice_seq = notices[-1][0]
        if world is not None or world_version != cursor.world_version:
            msg["world"] = world
            cursor.world_version = world_version
        return msg
