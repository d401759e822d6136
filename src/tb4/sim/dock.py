"""Create 3 docking semantics: when the dock is visible, when the robot counts as docked, and the dock/undock actions.

The dock pose is the robot's pose when docked; the station body is just ahead of it (+heading). The robot sees
the dock from behind that pose (the -heading half-plane), within `visible_distance`, when it faces the station
within `visible_half_angle`. Docking aligns the robot on the dock axis (turn, drive, turn) and then drives in
slowly; undocking reverses 0.4 m and turns 180 degrees. Both give up after 30 s of sim time and can be
cancelled. The actions are small state machines that only propose (v, w); the simulation drives the robot.
"""

from __future__ import annotations

import math

from tb4.core.geometry import Pose, wrap_angle
from tb4.core.robot_params import DockParams
from tb4.sim.goal_state import FAILED, RUNNING, SUCCEEDED, GoalState

__all__ = [
    "DockActionState",
    "dock_relative",
    "dock_visible",
    "is_docked",
    "DockAction",
    "UndockAction",
]


class DockActionState(GoalState):
    """Progress of a dock or undock goal, shared with the caller (feedback: sees_dock; result: is_docked)."""

    def __init__(self, kind: str, status: str = RUNNING, reason: str = "", sees_dock: bool = False) -> None:
        super().__init__(kind, status, reason)  # kind: "dock" or "undock"
        self.sees_dock = sees_dock
        self.is_docked = False

    def __repr__(self) -> str:
        return (
            f"DockActionState(kind={self.kind!r}, status={self.status!r}, reason={self.reason!r}, "
            f"sees_dock={self.sees_dock}, is_docked={self.is_docked})"
        )


def dock_relative(pose: Pose, dock: Pose) -> Pose:
    """The robot pose in the dock frame (origin at the docked pose, +x towards the station)."""
    dx, dy = pose[0] - dock[0], pose[1] - dock[1]
    c, s = math.cos(dock[2]), math.sin(dock[2])
    return (c * dx + s * dy, -s * dx + c * dy, wrap_angle(pose[2] - dock[2]))


def dock_visible(pose: Pose, dock: Pose, p: DockParams) -> bool:
    """Behind the docked pose, close enough, and facing the station."""
    px, py, th = dock_relative(pose, dock)
    if px > p.docked_distance or math.hypot(px, py) > p.visible_distance:
        return False
    bearing = math.atan2(-py, p.station_offset - px)  # direction to the station, dock frame
    return abs(wrap_angle(bearing - th)) <= math.radians(p.visible_half_angle)


def is_docked(pose: Pose, dock: Pose, p: DockParams) -> bool:
    dx, dy = pose[0] - dock[0], pose[1] - dock[1]
    if dx * dx + dy * dy > (p.docked_distance + 1e-6) ** 2:  # clearly away (a rotation keeps the distance): the
        return False  # common case, every physics step, without the rotation; near the bound, the exact test below
    px, py, th = dock_relative(pose, dock)
    return math.hypot(px, py) <= p.docked_distance and abs(th) <= p.docked_yaw


def _turn_rate(err: float, turn_speed: float) -> float:
    """Proportional turn with a floor so the last degrees do not take forever."""
    w = max(-turn_speed, min(turn_speed, 2.5 * err))
    return math.copysign(max(abs(w), 0.08), err)


_HEADING_TOL = 0.01  # rad, turn phases end when this close
_LATERAL_TOL = 0.006  # m off the dock axis that the final approach can absorb


class DockAction:
    """Dock: align on the dock axis (turn, drive, turn) when off it, then drive in slowly."""

    def __init__(self, dock: Pose, params: DockParams, start_time: float, state: DockActionState) -> None:
        self.dock = dock
        self.p = params
        self.deadline = start_time + params.action_timeout
        self.state = state
        self.phase = "plan"
        self.target = (0.0, 0.0)  # alignment point on the dock axis, dock frame

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        """Velocity to apply for the next step."""
        px, py, th = dock_relative(pose, self.dock)
        p = self.p
        if self.phase == "plan":
            if abs(py) <= _LATERAL_TOL and px <= 0.0:
                self.phase = "turn_in"
            else:
                self.target = (min(px + abs(py), -0.05), 0.0)  # reach the axis at 45 degrees
                self.phase = "turn_to_axis"
        if self.phase == "turn_to_axis":
            err = wrap_angle(math.atan2(self.target[1] - py, self.target[0] - px) - th)
            if abs(err) > _HEADING_TOL:
                return (0.0, _turn_rate(err, p.turn_speed))
            self.phase = "drive_to_axis"
        if self.phase == "drive_to_axis":
            tx, ty = self.target[0] - px, self.target[1] - py
            dist = math.hypot(tx, ty)
            c, s = math.cos(th), math.sin(th)
            ahead = c * tx + s * ty
            if dist > 0.003 and ahead > 0.0:
                err = wrap_angle(math.atan2(ty, tx) - th) if dist > 0.02 else 0.0
                v = min(p.approach_speed * 2.0, max(0.02, 1.5 * dist))
                return (v, max(-p.turn_speed, min(p.turn_speed, 2.0 * err)))
            self.phase = "turn_in"
        if self.phase == "turn_in":
            if abs(th) > _HEADING_TOL:
                return (0.0, _turn_rate(-th, p.turn_speed))
            self.phase = "approach"
        if self.phase == "approach":
            if px < -0.003:
                heading = -math.atan(4.0 * py)
                v = min(p.approach_speed, max(0.015, 1.5 * -px))
                return (v, max(-p.turn_speed, min(p.turn_speed, 2.0 * wrap_angle(heading - th))))
            self.phase = "settle"
        return (0.0, 0.0)

    def update(self, pose: Pose, time: float, bumped: bool) -> None:
        """After a physics step: success, retry or give up."""
        docked = is_docked(pose, self.dock, self.p)
        if docked and (self.phase == "settle" or (bumped and self.phase == "approach")):
            self.state.finish(SUCCEEDED, "docked")
        elif self.phase == "settle":
            self.phase = "plan"  # missed: align again
        if not self.state.done and time >= self.deadline - 1e-9:
            self.state.finish(FAILED, f"dock timed out after {self.p.action_timeout:g} s")


class UndockAction:
    """Undock: reverse `undock_distance`, then turn 180 degrees in place."""

    def __init__(self, start: Pose, params: DockParams, start_time: float, state: DockActionState) -> None:
        self.start = start
        self.p = params
        self.deadline = start_time + params.action_timeout
        self.state = state
        self.phase = "reverse"
        self.goal_yaw = wrap_angle(start[2] + math.pi)

    def command(self, pose: Pose, time: float) -> tuple[float, float]:
        p = self.p
        if self.phase == "reverse":
            left = p.undock_distance - math.hypot(pose[0] - self.start[0], pose[1] - self.start[1])
            if left > 0.002:
                return (-min(p.undock_speed, max(0.02, 1.5 * left)), 0.0)
            self.phase = "turn"
        if self.phase == "turn":
            err = wrap_angle(self.goal_yaw - pose[2])
            if abs(err) > _HEADING_TOL:
                # keep turning counter-clockwise until close, so a 180 deg turn does not dither at +-pi
                return (0.0, _turn_rate(err if abs(err) < 1.0 else abs(err), p.turn_speed))
            self.phase = "done"
        return (0.0, 0.0)

    def update(self, pose: Pose, time: float, bumped: bool) -> None:
        if self.phase == "done":
            self.state.finish(SUCCEEDED, "undocked")
        elif time >= self.deadline - 1e-9:
            self.state.finish(FAILED, f"undock timed out after {self.p.action_timeout:g} s")
