"""What the viewer knows about one robot: the newest value of each topic, and snapshots of it for the page.

The ROS bridge writes plain values here (never messages, no rclpy), the web server reads bounded-rate snapshots.
Everything is a latest-value cache or a bounded ring, so a fast simulator or a slow browser never grows memory.
Grids go to the page as indexed PNG images (one byte per cell, palette with alpha), encoded lazily and cached.
"""

from __future__ import annotations

import math
import struct
import threading
import time
import zlib
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tb4.core import robot_params
from tb4.core.geometry import compose

__all__ = [
    "LAYERS",
    "MAP_PALETTE",
    "COSTMAP_PALETTE",
    "Grid",
    "encode_indexed_png",
    "grid_png",
    "RealTimeFactor",
    "Trail",
    "TaskTracker",
    "ClientCursor",
    "ViewerState",
    "ACTIVE_STATUSES",
    "STATUS_NAMES",
]

#: Grid layers the page can draw, with the least wall time between two sends of a new version to one page.
LAYERS: dict[str, float] = {"map": 0.0, "global_costmap": 1.0, "local_costmap": 0.2}

#: action_msgs/GoalStatus values.
STATUS_NAMES = {
    0: "unknown",
    1: "accepted",
    2: "executing",
    3: "canceling",
    4: "succeeded",
    5: "canceled",
    6: "aborted",
}
ACTIVE_STATUSES = (1, 2, 3)

TRAIL_LENGTH = 4000  # points kept of the driven trail
TRAIL_STEP = 0.05  # m between two trail points
PARTICLE_POINTS = 600  # particle cloud points sent per state message, at most
PLAN_POINTS = 400  # most points of a plan sent to the page
RELOCALIZED = 0.3  # m or rad: a map->odom change this large (a new initial pose) restarts the trail


def _palette_map() -> np.ndarray:
    """OccupancyGrid values (0..100, -1 as 255) to RGBA: free white, occupied near-black, unknown grey."""
    pal = np.zeros((256, 4), dtype=np.uint8)
    values = np.arange(101)
    shade = (250 - values * 2.25).astype(np.uint8)  # 0 -> 250 (free) ... 100 -> 25 (wall)
    pal[:101, 0] = shade
    pal[:101, 1] = shade
    pal[:101, 2] = shade
    pal[:101, 3] = 255
    pal[101:255] = (120, 120, 140, 255)  # out-of-range values: visible, never confused with free space
    pal[255] = (176, 184, 194, 255)  # unknown (-1)
    return pal


def _palette_costmap() -> np.ndarray:
    """Costmap values (0..100 scaled from Nav2's 0..254) to translucent RGBA, close to RViz's 'costmap' scheme."""
    pal = np.zeros((256, 4), dtype=np.uint8)
    for v in range(1, 99):  # inflation: blue (low cost) through green/yellow to red (high cost)
        t = v / 98.0
        pal[v] = (int(255 * min(1.0, 2 * t)), int(255 * min(1.0, 2 - 2 * t) * 0.85), int(255 * (1 - t) ** 2), 110)
    pal[99] = (0, 190, 225, 150)  # inscribed: cyan
    pal[100] = (170, 40, 200, 150)  # lethal: purple
    pal[255] = (0, 0, 0, 0)  # unknown: transparent
    return pal


MAP_PALETTE = _palette_map()
COSTMAP_PALETTE = _palette_costmap()


def encode_indexed_png(pixels: np.ndarray, palette: np.ndarray) -> bytes:
    """An 8-bit indexed PNG (PLTE + tRNS) of `pixels` (uint8, row 0 at the top). Small and fast for grids."""
    pixels = np.ascontiguousarray(pixels, dtype=np.uint8)
    if pixels.ndim != 2 or pixels.size == 0:
        raise ValueError("pixels must be a non-empty 2D array")
    height, width = pixels.shape
    palette = np.asarray(palette, dtype=np.uint8).reshape(256, 4)

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)

    raw = np.empty((height, width + 1), dtype=np.uint8)
    raw[:, 0] = 0  # filter type "none" on every row
    raw[:, 1:] = pixels
    header = struct.pack(">IIBBBBB", width, height, 8, 3, 0, 0, 0)
    return b"".join(
        (
            b"\x89PNG\r\n\x1a\n",
            chunk(b"IHDR", header),
            chunk(b"PLTE", palette[:, :3].tobytes()),
            chunk(b"tRNS", palette[:, 3].tobytes()),
            chunk(b"IDAT", zlib.compress(raw.tobytes(), 6)),
            chunk(b"IEND", b""),
        )
    )


@dataclass(frozen=True)
class Grid:
    """An OccupancyGrid as plain values: `data[row, col]` int8 with row 0 at origin_y (bottom)."""

    data: np.ndarray
    resolution: float
    origin_x: float
    origin_y: float
    frame: str = "map"
    origin_yaw: float = 0.0

    @property
    def width(self) -> int:
        return int(self.data.shape[1])

    @property
    def height(self) -> int:
        return int(self.data.shape[0])

    def signature(self) -> tuple[int, int, float, float, float]:
        return (self.width, self.height, round(self.resolution, 6), round(self.origin_x, 4), round(self.origin_y, 4))


def grid_png(grid: Grid, palette: np.ndarray) -> bytes:
    """PNG of a grid as the page draws it: top row = highest y, so flip the bottom-up grid."""
    pixels = np.asarray(grid.data, dtype=np.int8).view(np.uint8)[::-1]
    return encode_indexed_png(pixels, palette)


class RealTimeFactor:
    """Sim seconds per wall second over a sliding window of (wall, sim) samples."""

    def __init__(self, window: float = 2.0, clock: Callable[[], float] = time.monotonic) -> None:
        self.window = window
        self.clock = clock
        self._samples: deque[tuple[float, float]] = deque(maxlen=256)

    def add(self, sim_time: float, wall: float | None = None) -> None:
        wall = self.clock() if wall is None else wall
        if self._samples and sim_time < self._samples[-1][1]:
            self._samples.clear()  # the clock went backwards: a restarted simulator
        if self._samples and wall - self._samples[-1][0] < 0.02:
            return  # keep the ring meaningful at any message rate
        self._samples.append((wall, sim_time))
        while len(self._samples) > 2 and wall - self._samples[0][0] > self.window:
            self._samples.popleft()

    def value(self, wall: float | None = None) -> float | None:
        """None until two samples span 0.2 s; 0 when the clock stopped for longer than the window."""
        if len(self._samples) < 2:
            return None
        wall = self.clock() if wall is None else wall
        (w0, s0), (w1, s1) = self._samples[0], self._samples[-1]
        if wall - w1 > self.window:
            return 0.0
        if w1 - w0 < 0.2:
            return None
        return max(0.0, (s1 - s0) / (w1 - w0))


class Trail:
    """The driven path: bounded, points at least TRAIL_STEP apart, numbered so each page gets only new ones."""

    def __init__(self, maxlen: int = TRAIL_LENGTH, step: float = TRAIL_STEP) -> None:
        self.step = step
        self.points: deque[tuple[int, float, float]] = deque(maxlen=maxlen)
        self.seq = 0
        self.epoch = 0  # bumped when the trail restarts; pages then drop what they have

    def add(self, x: float, y: float) -> None:
        if not (math.isfinite(x) and math.isfinite(y)):
            return
        if self.points:
            # Samples may be far apart (a fast simulator, a busy machine): only relocalization restarts the trail.
            _, lx, ly = self.points[-1]
            if math.hypot(x - lx, y - ly) < self.step:
                return
        self.seq += 1
        self.points.append((self.seq, x, y))

    def clear(self) -> None:
        self.points.clear()
        self.epoch += 1

    def since(self, epoch: int, seq: int) -> tuple[bool, list[float], int]:
        """(reset, flat [x, y, ...] points after `seq`, newest seq) for a page that has (epoch, seq)."""
        reset = epoch != self.epoch
        start = -1 if reset else seq
        flat: list[float] = []
        for s, x, y in self.points:
            if s > start:
                flat.extend((round(x, 3), round(y, 3)))
        return reset, flat, self.seq


@dataclass
class _Goal:
    action: str
    goal_id: str
    status: int
    updated: float
    feedback: dict[str, Any] = field(default_factory=dict)


class TaskTracker:
    """Goal statuses and feedback of the navigation actions (from their hidden status/feedback topics).

    The current task is the most recently updated active goal, else the last one that finished.
    """

    MAX_GOALS = 32

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self._goals: dict[tuple[str, str], _Goal] = {}

    def _trim(self) -> None:
        if len(self._goals) > self.MAX_GOALS:
            for key, _ in sorted(self._goals.items(), key=lambda kv: kv[1].updated)[: len(self._goals) // 2]:
                del self._goals[key]

    def on_status(self, action: str, statuses: Sequence[tuple[str, int]]) -> list[tuple[str, int]]:
        """Record a status array; returns the (goal_id, status) pairs that changed."""
        now = self.clock()
        changed = []
        for goal_id, status in statuses:
            key = (action, goal_id)
            goal = self._goals.get(key)
            if goal is None:
                self._goals[key] = goal = _Goal(action, goal_id, int(status), now)
                changed.append((goal_id, int(status)))
            elif goal.status != status:
                goal.status, goal.updated = int(status), now
                changed.append((goal_id, int(status)))
        self._trim()
        return changed

    def on_feedback(self, action: str, goal_id: str, feedback: dict[str, Any]) -> None:
        key = (action, goal_id)
        goal = self._goals.get(key)
        if goal is None:
            self._goals[key] = goal = _Goal(action, goal_id, 2, self.clock())
        elif goal.status not in ACTIVE_STATUSES:
            return  # late feedback after the result
        goal.feedback = dict(feedback)
        goal.updated = self.clock()
        self._trim()

    def current(self) -> dict[str, Any] | None:
        if not self._goals:
            return None
        active = [g for g in self._goals.values() if g.status in ACTIVE_STATUSES]
        goal = max(active or self._goals.values(), key=lambda g: g.updated)
        return {
            "action": goal.action,
            "goal_id": goal.goal_id,
            "status": STATUS_NAMES.get(goal.status, str(goal.status)),
            "active": goal.status in ACTIVE_STATUSES,
            **goal.feedback,
        }

    def active_goals(self) -> list[tuple[str, str]]:
        return [(g.action, g.goal_id) for g in self._goals.values() if g.status in ACTIVE_STATUSES]


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
            if robot is not None:
                self.trail.add(robot[0], robot[1])

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

    def notice(self, level: str, text: str) -> None:
        """A message for every page (goal accepted, aborted with a reason, ...)."""
        with self._lock:
            self._notice_seq += 1
            self._notices.append((self._notice_seq, level, text[:300]))

    # --- readers -------------------------------------------------------------------------------------------
    def _robot_pose_locked(self) -> tuple[float, float, float] | None:
        if self.odom_base is None:
            return None
        if self.map_odom is None:
            return self.odom_base  # not localized yet: draw odom as if it were the map (labelled so on the page)
        return compose(self.map_odom, self.odom_base)

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

    def snapshot(self, cursor: ClientCursor, wall: float | None = None) -> dict[str, Any]:
        """The page's next `state` message; advances `cursor` past what it includes."""
        with self._lock:
            pose = self._robot_pose_locked()
            localized = self.map_odom is not None
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
            msg["robot"] = {
                "x": _r(pose[0]),
                "y": _r(pose[1]),
                "yaw": _r(pose[2]),
                "localized": localized,
                "frame": "map" if localized else "odom",
                "v": _r(v, 2),
                "w": _r(w, 2),
                "radius": self.robot_radius,
            }
            msg["scan"] = self._scan_points(pose)
        if self.amcl is not None:
            msg["amcl"] = {"x": _r(self.amcl[0]), "y": _r(self.amcl[1]), "yaw": _r(self.amcl[2])}
        if plan is not None:
            step = max(1, math.ceil(len(plan) / PLAN_POINTS))
            pts = plan[::step, :2]
            if len(plan) and step > 1:
                pts = np.vstack([pts, plan[-1:, :2]])
            msg["plan"] = {"frame": plan_frame, "points": np.round(pts, 3).ravel().tolist()}
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
