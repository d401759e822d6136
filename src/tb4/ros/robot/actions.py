"""The Create 3's action servers: dock, undock, the drive goals, led_animation and audio_note_sequence.

Each goal becomes a core object stepped by the simulation (tb4.sim.motion, tb4.sim.ui), served through the shared
TaskActionServer. Malformed goals (NaN, negative speeds, zero radius, a goal 1 km away, ...) are rejected at
once with the reason in the simulator's log; goals the robot cannot run now (e-stop, lifted, powered off) too.
A drive goal preempts the running one, which ends aborted, as on the robot.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

from irobot_create_msgs.action import (
    AudioNoteSequence,
    Dock,
    DriveArc,
    DriveDistance,
    LedAnimation,
    NavigateToPosition,
    RotateAngle,
    Undock,
    WallFollow,
)
from rclpy.node import Node

from tb4.core.geometry import Pose
from tb4.ros.action_bridge import TaskActionServer
from tb4.ros.convert import checked_pose, duration_to_seconds, pose_stamped
from tb4.ros.loop import LoopView
from tb4.ros.run_record import RobotRecord
from tb4.sim import motion
from tb4.sim.goal_state import FAILED
from tb4.sim.ui import AudioSequence, Note
from tb4.sim.ui import LedAnimation as LedAnimationTask

__all__ = ["Create3Actions"]

T = TypeVar("T")


def _zero() -> Pose:
    return (0.0, 0.0, 0.0)


class Create3Actions:
    """Registers every Create 3 action server on `node`."""

    def __init__(self, node: Node, loop: LoopView, frames: dict[str, str], record: RobotRecord | None) -> None:
        self.node = node
        self.loop = loop
        self.sim = loop.sim
        self.frames = frames
        self.servers: list[TaskActionServer] = []
        self._accepted = itertools.count(1)  # acceptance order of drive goals (any of the five actions)
        self._order: dict[int, int] = {}  # id(goal request) -> acceptance number, until the goal starts
        self._order_lock = threading.Lock()
        self._latest = 0  # acceptance number of the newest drive goal started (loop thread)
        serve = self._serve
        sim = self.sim
        inputs = loop.inputs
        serve(
            Dock,
            "dock",
            lambda _g: inputs.sim.start_dock(),
            lambda _g: self._accept_dock("dock"),
            record,
            result=lambda _t: {"is_docked": sim.is_docked()},
            feedback=lambda t: {"sees_dock": bool(t.sees_dock)},
        )
        serve(
            Undock,
            "undock",
            lambda _g: inputs.sim.start_undock(),
            lambda _g: self._accept_dock("undock"),
            record,
            result=lambda _t: {"is_docked": sim.is_docked()},
            feedback=lambda _t: {},
        )
        self._motion(DriveDistance, "drive_distance", self._drive_distance, record)
        self._motion(RotateAngle, "rotate_angle", self._rotate_angle, record)
        self._motion(DriveArc, "drive_arc", self._drive_arc, record)
        self._motion(NavigateToPosition, "navigate_to_position", self._navigate, record)
        self._motion(
            WallFollow,
            "wall_follow",
            self._wall_follow,
            record,
            result=lambda t: {"runtime": t.result_extra.get("runtime", 0.0)},
        )
        serve(LedAnimation, "led_animation", self._start_led, lambda g: self._valid(lambda: self._led(g, 0.0)), record)
        serve(
            AudioNoteSequence,
            "audio_note_sequence",
            self._start_audio,
            lambda g: self._valid(lambda: self._audio(g, 0.0)),
            record,
        )

    # ------------------------------------------------------------------ plumbing
    def _serve(
        self,
        action_type: Any,
        name: str,
        start: Callable[[Any], Any],
        accept: Callable[[Any], bool],
        record: RobotRecord | None,
        result: Callable[[Any], dict[str, Any]] | None = None,
        feedback: Callable[[Any], dict[str, Any]] | None = None,
    ) -> None:
        self.servers.append(
            TaskActionServer(
                self.node,
                self.loop,
                action_type,
                name,
                start,
                stamp=lambda: self.sim.time,
                result_fields=result,
                feedback_fields=feedback,
                accept=accept,
                record=record,
            )
        )

    def _motion(
        self,
        action_type: Any,
        name: str,
        fields_of: Callable[[Any], tuple[Any, ...]],
        record: RobotRecord | None,
        result: Callable[[Any], dict[str, Any]] | None = None,
    ) -> None:
        """A drive goal's server; `fields_of(goal)`: its fields as plain values, which build the core's goal
        (tb4.sim.motion.build_drive_goal) and make its start a journaled input."""

        def start(goal: Any) -> Any:
            # Goals start on executor threads, not always in the order they were accepted: the newest accepted
            # goal wins, and an older one that starts after it ends at once, as if preempted.
            with self._order_lock:
                seq = self._order.pop(id(goal), 0)
            if seq < self._latest:
                raise ValueError(f"{name} preempted by a newer drive goal before it started")
            self._latest = seq
            return self.loop.inputs.sim.start_drive_goal(name, *fields_of(goal))

        def accept(goal: Any) -> bool:
            drive = self.sim.params.drive
            if not self._valid(lambda: motion.build_drive_goal(name, _zero, drive, fields_of(goal)), name):
                return False
            refusal = self.loop.call(self.sim.base.refuse_motion)
            if refusal:
                self.node.get_logger().warn(f"{name} goal rejected: {refusal}")
                return False
            with self._order_lock:
                self._order[id(goal)] = next(self._accepted)
            return True

        fields = result or self._pose_result

        def ended(state: Any) -> dict[str, Any]:
            """The result fields; an aborted goal's reason goes to the log (Create 3 results carry none)."""
            if state.status == FAILED:
                self.node.get_logger().warn(f"{name} aborted: {state.reason}")
            return fields(state)

        self._serve(action_type, name, start, accept, record, result=ended)

    def _valid(self, build: Callable[[], Any], name: str = "goal") -> bool:
        try:
            build()
        except (ValueError, TypeError) as exc:
            self.node.get_logger().warn(f"{name} goal rejected: {exc}")
            return False
        return True

    def _odom(self) -> Pose:
        o = self.sim.odometry()
        return (o.x, o.y, o.yaw)

    def _pose_result(self, state: Any) -> dict[str, Any]:
        pose = state.final_pose if state.final_pose is not None else self._odom()
        return {"pose": pose_stamped(pose, self.sim.time, self.frames["odom"])}

    def _accept_dock(self, action: str) -> bool:
        """Create 3 rejects dock when docked or the dock is not visible, and undock when not docked."""
        refusal = self.loop.call(self.sim.base.refuse_motion)
        if refusal:
            self.node.get_logger().warn(f"{action} goal rejected: {refusal}")
            return False
        if action == "dock":
            ok, why = self.loop.call(lambda: (not self.sim.is_docked() and self.sim.dock_visible(), ""))
            if not ok:
                docked = self.loop.call(self.sim.is_docked)
                why = "already docked" if docked else "dock not visible"
        else:
            ok = self.loop.call(self.sim.is_docked)
            why = "not docked"
        if not ok:
            self.node.get_logger().warn(f"{action} goal rejected: {why}")
        return bool(ok)

    # ------------------------------------------------------------------ goals -> plain fields
    def _drive_distance(self, g: Any) -> tuple[Any, ...]:
        return (g.distance, g.max_translation_speed)

    def _rotate_angle(self, g: Any) -> tuple[Any, ...]:
        return (g.angle, g.max_rotation_speed)

    def _drive_arc(self, g: Any) -> tuple[Any, ...]:
        return (g.translate_direction, g.angle, g.radius, g.max_translation_speed)

    def _navigate(self, g: Any) -> tuple[Any, ...]:
        frame = g.goal_pose.header.frame_id
        if frame not in ("", self.frames["odom"], "odom"):
            raise ValueError(f"goal_pose is in frame '{frame}': the Create 3 drives to odometry positions ('odom')")
        goal = checked_pose(g.goal_pose.pose, "goal_pose")
        return (goal, g.achieve_goal_heading, g.max_translation_speed, g.max_rotation_speed)

    def _wall_follow(self, g: Any) -> tuple[Any, ...]:
        return (g.follow_side, duration_to_seconds(g.max_runtime))

    def _led(self, g: Any, now: float) -> LedAnimationTask:
        leds = [(c.red, c.green, c.blue) for c in g.lightring.leds]
        return LedAnimationTask(int(g.animation_type), leds, duration_to_seconds(g.max_runtime), now)

    def _start_led(self, g: Any) -> LedAnimationTask:
        task = self._led(g, self.sim.time)
        return self._take_over(self.sim.base.lightring, "animation", task, "a led_animation goal")

    def _audio(self, g: Any, now: float) -> AudioSequence:
        notes = [Note(int(n.frequency), duration_to_seconds(n.max_runtime)) for n in g.note_sequence.notes]
        return AudioSequence(notes, int(g.iterations), now)

    def _start_audio(self, g: Any) -> AudioSequence:
        task = self._audio(g, self.sim.time)
        return self._take_over(self.sim.base.speaker, "sequence", task, "an audio_note_sequence goal")

    def _take_over(self, holder: Any, slot: str, task: T, what: str) -> T:
        """Put `task` in `holder.slot` (the light ring's animation, the speaker's sequence), preempting the one
        there: in the loop, outside the replay (neither changes any robot's motion)."""

        def swap() -> T:
            running = getattr(holder, slot)
            if running is not None:
                running.preempt()
            setattr(holder, slot, task)
            return task

        return self.loop.call_outside_replay(swap, what, moves=False)
