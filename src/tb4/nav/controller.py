"""Regulated Pure Pursuit (Nav2's RPP, re-derived), goal checker and progress checker.

Why RPP: it is what TurtleBot 4 users get from Nav2's behaviour (follow the global path smoothly, slow down in
tight turns and near obstacles, turn in place at the start and at the goal) at a cost of microseconds per step.
The controller never commands an arc that would enter an inscribed/lethal cell of the LOCAL costmap within
`max_allowed_time_to_collision_up_to_carrot`: it stops and reports `collision` instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tb4.core import robot_params
from tb4.core.geometry import Pose, arc_pose, wrap_angle

__all__ = [
    "INSCRIBED_COST",
    "LETHAL_COST",
    "NO_INFORMATION_COST",
    "costs_at",
    "cost_at",
    "footprint_in_collision",
    "arc_poses",
    "ControlResult",
    "RegulatedPurePursuit",
    "GoalChecker",
    "ProgressChecker",
]

# Nav2 cost values (same as tb4.nav.costmap's INSCRIBED / LETHAL / NO_INFORMATION).
INSCRIBED_COST = 253
LETHAL_COST = 254
NO_INFORMATION_COST = 255


def costs_at(costmap: Any, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    """Costs at world points (vectorized); NO_INFORMATION off the map."""
    xs = np.asarray(xs, dtype=float)
    ys = np.asarray(ys, dtype=float)
    data = costmap.data
    cols = np.floor((xs - costmap.origin_x) / costmap.resolution).astype(np.int64)
    rows = np.floor((ys - costmap.origin_y) / costmap.resolution).astype(np.int64)
    inside = (rows >= 0) & (rows < data.shape[0]) & (cols >= 0) & (cols < data.shape[1])
    out = np.full(xs.shape, NO_INFORMATION_COST, dtype=np.int64)
    out[inside] = data[rows[inside], cols[inside]]
    return out


def cost_at(costmap: Any, x: float, y: float) -> int:
    """Cost at one world point (NO_INFORMATION off the map): costs_at without the array overhead, same cells."""
    data = costmap.data
    col = math.floor((x - costmap.origin_x) / costmap.resolution)
    row = math.floor((y - costmap.origin_y) / costmap.resolution)
    if 0 <= row < data.shape[0] and 0 <= col < data.shape[1]:
        return int(data[row, col])
    return NO_INFORMATION_COST


def footprint_in_collision(
    costmap: Any,
    x: np.ndarray | float,
    y: np.ndarray | float,
    radius: float,
    direction: np.ndarray | float | None = None,
) -> np.ndarray:
    """For circle footprints centred at (x, y): does a sampled footprint point lie on a LETHAL cell?

    That is Nav2's behaviour-server check for a round robot (footprint cost >= LETHAL). Without `direction`
    the whole perimeter and the centre are sampled; with it (the heading of motion, radians) only the leading
    half of the perimeter, which is where any new contact starts: a robot touching the dock behind it can still
    drive away from it.
    """
    x = np.atleast_1d(np.asarray(x, dtype=float))
    y = np.atleast_1d(np.asarray(y, dtype=float))
    n = 24
    if direction is None:
        ang = np.broadcast_to(np.linspace(0.0, 2.0 * math.pi, n, endpoint=False), (len(x), n))
        px = np.concatenate([x[:, None], x[:, None] + radius * np.cos(ang)], axis=1)
        py = np.concatenate([y[:, None], y[:, None] + radius * np.sin(ang)], axis=1)
    else:
        d = np.broadcast_to(np.atleast_1d(np.asarray(direction, dtype=float)), x.shape)
        ang = d[:, None] + np.linspace(-0.5 * math.pi, 0.5 * math.pi, n // 2 + 1)[None, :]
        px = x[:, None] + radius * np.cos(ang)
        py = y[:, None] + radius * np.sin(ang)
    c = costs_at(costmap, px, py)
    return np.any(c == LETHAL_COST, axis=1)


def arc_poses(pose: Pose, v: float, w: float, duration: float, step: float) -> np.ndarray:
    """Poses (N, 3) along the unicycle arc of command (v, w) from `pose`, every `step` seconds up to `duration`."""
    n = max(1, int(math.ceil(duration / step)))
    t = np.linspace(step, n * step, n)
    yaw = pose[2] + w * t
    if abs(w) < 1e-9:
        x = pose[0] + v * t * math.cos(pose[2])
        y = pose[1] + v * t * math.sin(pose[2])
    else:
        x = pose[0] + v / w * (np.sin(yaw) - math.sin(pose[2]))
        y = pose[1] - v / w * (np.cos(yaw) - math.cos(pose[2]))
    out = np.empty((n, 3))
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = yaw
    return out


@dataclass
class ControlResult:
    """One control step: the command and why (status: ok | rotating | collision | invalid_path)."""

    v: float
    w: float
    status: str = "ok"
    message: str = ""


class RegulatedPurePursuit:
    """Pure pursuit with adaptive lookahead, rotate-to-heading, curvature/cost/approach regulation."""

    def __init__(
        self,
        rpp: dict[str, Any],
        *,
        max_linear_vel: float = 0.26,
        max_angular_vel: float = 1.0,
        xy_goal_tolerance: float = 0.25,
        robot_radius: float | None = None,
        inflation_cost_scaling_factor: float | None = None,
    ) -> None:
        self.p = dict(rpp)
        self.desired_v = min(float(self.p["desired_linear_vel"]), max_linear_vel)
        self.max_w = min(float(self.p["max_angular_vel"]), max_angular_vel)
        self.rotate_w = min(float(self.p["rotate_to_heading_angular_vel"]), self.max_w)
        self.lin_acc = float(self.p["max_linear_accel"])
        self.ang_acc = float(self.p["max_angular_accel"])
        self.xy_goal_tolerance = float(xy_goal_tolerance)
        self.robot_radius = float(robot_radius if robot_radius is not None else robot_params.robot_radius())
        self.cost_factor = float(
            inflation_cost_scaling_factor
            if inflation_cost_scaling_factor is not None
            else self.p["inflation_cost_scaling_factor"]
        )
        self.path: np.ndarray = np.zeros((0, 3))
        self._cum = np.zeros(0)
        self._idx = 0
        self._final_rotation = False
        self.last_cmd = (0.0, 0.0)
        self.carrot: tuple[float, float] | None = None

    # --- plan handling -------------------------------------------------------------------------------
    def set_plan(self, path: np.ndarray) -> None:
        """Follow `path` (N, 3). Keeps the final-rotation latch when only the route (not the goal) changed."""
        path = np.asarray(path, dtype=float).reshape(-1, 3) if len(path) else np.zeros((0, 3))
        if len(path) == 0 or not np.all(np.isfinite(path)):
            raise ValueError("path is empty or not finite")
        same_goal = len(self.path) > 0 and np.allclose(self.path[-1], path[-1], atol=1e-6)
        self.path = path
        seg = np.hypot(*np.diff(path[:, :2], axis=0).T) if len(path) > 1 else np.zeros(0)
        self._cum = np.concatenate([[0.0], np.cumsum(seg)])
        self._idx = 0
        if not same_goal:
            self._final_rotation = False

    def reset(self) -> None:
        self.path = np.zeros((0, 3))
        self._cum = np.zeros(0)
        self._idx = 0
        self._final_rotation = False
        self.last_cmd = (0.0, 0.0)
        self.carrot = None

    @property
    def goal(self) -> Pose | None:
        if len(self.path) == 0:
            return None
        g = self.path[-1]
        return (float(g[0]), float(g[1]), float(g[2]))

    def _closest_index(self, pose: Pose) -> int:
        """Closest path point at or after the last one, searched within a window so loops are not skipped."""
        start = self._idx
        window_end = int(np.searchsorted(self._cum, self._cum[start] + 2.0 * float(self.p["max_lookahead_dist"])))
        end = min(len(self.path), max(window_end + 1, start + 1))
        seg = self.path[start:end, :2]
        d = np.hypot(seg[:, 0] - pose[0], seg[:, 1] - pose[1])
        self._idx = start + int(np.argmin(d))
        return self._idx

    def distance_remaining(self, pose: Pose) -> float:
        """Distance along the path from the robot to its end (for feedback and ETA)."""
        if len(self.path) == 0:
            return 0.0
        i = self._closest_index(pose)
        return float(math.hypot(self.path[i, 0] - pose[0], self.path[i, 1] - pose[1]) + self._cum[-1] - self._cum[i])

    CARROT_CHUNK = 64  # path points looked at per round when finding the first one beyond the lookahead

    def _carrot(self, pose: Pose, lookahead: float) -> tuple[float, float]:
        i = self._closest_index(pose)
        pts = self.path[i:, :2]
        # the first point at least `lookahead` away, looked for a chunk at a time: it is usually within the first
        # few points, and the remaining path can be thousands long
        j = -1
        for k in range(0, len(pts), self.CARROT_CHUNK):
            chunk = pts[k : k + self.CARROT_CHUNK]
            beyond = np.flatnonzero(np.hypot(chunk[:, 0] - pose[0], chunk[:, 1] - pose[1]) >= lookahead)
            if len(beyond):
                j = k + int(beyond[0])
                break
        if j < 0:
            return (float(pts[-1, 0]), float(pts[-1, 1]))
        if j == 0:
            return (float(pts[0, 0]), float(pts[0, 1]))
        # intersect the segment pts[j-1] -> pts[j] with the lookahead circle
        p0 = pts[j - 1] - (pose[0], pose[1])
        p1 = pts[j] - (pose[0], pose[1])
        dv = p1 - p0
        a = float(dv @ dv)
        b = 2.0 * float(p0 @ dv)
        c = float(p0 @ p0) - lookahead * lookahead
        disc = max(0.0, b * b - 4.0 * a * c)
        t = (-b + math.sqrt(disc)) / (2.0 * a) if a > 1e-12 else 1.0
        t = min(1.0, max(0.0, t))
        q = p0 + t * dv
        return (float(q[0] + pose[0]), float(q[1] + pose[1]))

    # --- control -------------------------------------------------------------------------------------
    def _rotate(self, angle: float, dt: float) -> float:
        sign = 1.0 if angle > 0.0 else -1.0
        w = sign * self.rotate_w
        w0 = self.last_cmd[1]
        w = min(max(w, w0 - self.ang_acc * dt), w0 + self.ang_acc * dt)
        stop_w = math.sqrt(2.0 * self.ang_acc * abs(angle))
        if abs(w) > stop_w:
            w = sign * stop_w
        return w

    def _cost_limited_speed(self, costmap: Any, pose: Pose, v: float) -> float:
        if costmap is None or not self.p["use_cost_regulated_linear_velocity_scaling"]:
            return v
        cost = cost_at(costmap, pose[0], pose[1])
        if cost <= 0 or cost >= INSCRIBED_COST:
            return v
        # invert Nav2's inflation: cost = 252 * exp(-factor * (d - inscribed))
        dist = self.robot_radius - math.log(cost / 252.0) / self.cost_factor
        scaling_dist = float(self.p["cost_scaling_dist"])
        if dist < scaling_dist:
            return v * float(self.p["cost_scaling_gain"]) * dist / scaling_dist
        return v

    def compute_velocity(self, pose: Pose, costmap: Any, dt: float) -> ControlResult:
        """Command for this control period; `costmap` is the local costmap (or None to skip checks)."""
        if len(self.path) == 0:
            return ControlResult(0.0, 0.0, "invalid_path", "no path to follow")
        v_prev, _ = self.last_cmd
        goal = self.path[-1]
        dist_goal_xy = math.hypot(goal[0] - pose[0], goal[1] - pose[1])
        remaining = self.distance_remaining(pose)
        at_end = self._idx >= len(self.path) - 1 or remaining < self.xy_goal_tolerance
        if self.p["use_rotate_to_heading"] and (
            self._final_rotation or (dist_goal_xy < self.xy_goal_tolerance and at_end)
        ):
            self._final_rotation = True
            w = self._rotate(wrap_angle(goal[2] - pose[2]), dt)
            self.carrot = (float(goal[0]), float(goal[1]))
            return self._finish(0.0, w, "rotating")

        if self.p["use_velocity_scaled_lookahead_dist"]:
            lookahead = abs(v_prev) * float(self.p["lookahead_time"])
            lookahead = min(max(lookahead, float(self.p["min_lookahead_dist"])), float(self.p["max_lookahead_dist"]))
        else:
            lookahead = float(self.p["lookahead_dist"])
        cx, cy = self._carrot(pose, lookahead)
        self.carrot = (cx, cy)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        lx = c * (cx - pose[0]) + s * (cy - pose[1])
        ly = -s * (cx - pose[0]) + c * (cy - pose[1])
        carrot_dist = math.hypot(lx, ly)
        angle_to_carrot = math.atan2(ly, lx)
        if self.p["use_rotate_to_heading"] and abs(angle_to_carrot) > float(self.p["rotate_to_heading_min_angle"]):
            return self._finish(0.0, self._rotate(angle_to_carrot, dt), "rotating")
        if carrot_dist < 1e-6:
            return self._finish(0.0, 0.0, "ok")

        curvature = 2.0 * ly / (carrot_dist * carrot_dist)
        v = self.desired_v
        if self.p["use_regulated_linear_velocity_scaling"]:
            radius = abs(1.0 / curvature) if abs(curvature) > 1e-9 else math.inf
            min_radius = float(self.p["regulated_linear_scaling_min_radius"])
            curv_v = v * radius / min_radius if radius < min_radius else v
            cost_v = self._cost_limited_speed(costmap, pose, v)
            v = min(curv_v, cost_v)
            v = max(v, min(float(self.p["regulated_linear_scaling_min_speed"]), self.desired_v))
        approach_dist = float(self.p["approach_velocity_scaling_dist"])
        if remaining < approach_dist:
            approach_v = max(self.desired_v * remaining / approach_dist, float(self.p["min_approach_linear_velocity"]))
            v = min(v, approach_v)
        v = min(max(v, v_prev - self.lin_acc * dt), v_prev + self.lin_acc * dt)
        v = max(0.0, min(v, self.desired_v))
        w = v * curvature
        if abs(w) > self.max_w:
            w = math.copysign(self.max_w, w)
            v = abs(w / curvature)
        if self.p["use_collision_detection"] and costmap is not None and v > 0.0:
            hit = self._collision_ahead(pose, v, w, carrot_dist, costmap)
            if hit is not None:
                self.last_cmd = (0.0, 0.0)
                return ControlResult(0.0, 0.0, "collision", f"collision ahead at ({hit[0]:.2f}, {hit[1]:.2f})")
        return self._finish(v, w, "ok")

    def _collision_ahead(self, pose: Pose, v: float, w: float, carrot_dist: float, costmap: Any) -> Pose | None:
        """First projected pose within the time/carrot horizon that enters an inscribed or lethal cell."""
        res = float(costmap.resolution)
        horizon = float(self.p["max_allowed_time_to_collision_up_to_carrot"])
        # project at least a couple of cells even while accelerating from rest, never past the carrot
        dist = min(max(v * horizon, 2.0 * res), max(carrot_dist, 2.0 * res))
        duration = dist / max(v, 1e-6)
        step = min(max(0.5 * res / max(v, 1e-6), 1e-3), duration)
        here = cost_at(costmap, pose[0], pose[1])
        threshold = LETHAL_COST if INSCRIBED_COST <= here < NO_INFORMATION_COST else INSCRIBED_COST
        # point by point up to the first hit: a dozen points, where NumPy's per-call cost (arc_poses + costs_at)
        # made this check a fifth of the controller's time
        for i in range(1, max(1, int(math.ceil(duration / step))) + 1):
            x, y, yaw = arc_pose(pose[0], pose[1], pose[2], v, w, i * step)
            cost = cost_at(costmap, x, y)
            if cost >= threshold and cost != NO_INFORMATION_COST:
                return (x, y, yaw)
        return None

    def _finish(self, v: float, w: float, status: str) -> ControlResult:
        w = max(-self.max_w, min(self.max_w, w))
        self.last_cmd = (v, w)
        return ControlResult(v, w, status)


class GoalChecker:
    """Nav2 SimpleGoalChecker: xy within tolerance, then yaw; `stateful` latches the xy check."""

    def __init__(self, xy_goal_tolerance: float = 0.25, yaw_goal_tolerance: float = 0.25, stateful: bool = True):
        self.xy_tol = float(xy_goal_tolerance)
        self.yaw_tol = float(yaw_goal_tolerance)
        self.stateful = bool(stateful)
        self._xy_reached = False

    def reset(self) -> None:
        self._xy_reached = False

    def xy_reached(self, pose: Pose, goal: Pose) -> bool:
        if self._xy_reached:
            return True
        ok = math.hypot(goal[0] - pose[0], goal[1] - pose[1]) <= self.xy_tol
        if ok and self.stateful:
            self._xy_reached = True
        return ok

    def is_goal_reached(self, pose: Pose, goal: Pose) -> bool:
        if not self.xy_reached(pose, goal):
            return False
        return abs(wrap_angle(goal[2] - pose[2])) <= self.yaw_tol


class ProgressChecker:
    """Nav2 SimpleProgressChecker: the robot must move `required_movement_radius` every `movement_time_allowance`."""

    def __init__(self, required_movement_radius: float = 0.5, movement_time_allowance: float = 10.0):
        self.radius = float(required_movement_radius)
        self.allowance = float(movement_time_allowance)
        self._baseline: Pose | None = None
        self._baseline_time = 0.0

    def reset(self) -> None:
        self._baseline = None

    def check(self, pose: Pose, now: float) -> bool:
        """False once the robot has not moved far enough for longer than the allowance."""
        if self._baseline is None or math.hypot(pose[0] - self._baseline[0], pose[1] - self._baseline[1]) > self.radius:
            self._baseline = pose
            self._baseline_time = now
            return True
        return now - self._baseline_time <= self.allowance
