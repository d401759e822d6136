"""The Create 3's services (reset_pose, e_stop, robot_power) and commands (cmd_lightring, cmd_audio), plus the
simulator's inputs for what a person does to the robot: `tb4_sim/press_button` and `tb4_sim/kidnap`.

Callbacks only validate and hand a function to the loop; a bad message is logged and dropped, never raised.

The robot's power is reported here too, beside robot_power: the battery falling below 10 % (the light ring pulses
red), running flat off the dock (the motors stop: an error line, once, and a `battery_empty` event in the run
record) and charging again on the dock, each once when it happens.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from geometry_msgs.msg import PoseStamped
from irobot_create_msgs.msg import AudioNoteVector, Button, LightringLeds
from irobot_create_msgs.srv import EStop, ResetPose, RobotPower
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data

from tb4.ros.convert import checked_pose, duration_to_seconds
from tb4.ros.loop import LoopView
from tb4.ros.replies import create_service
from tb4.ros.robot.common import RELIABLE
from tb4.ros.run_record import RobotRecord
from tb4.sim.battery import LOW_LEVEL
from tb4.sim.create3 import BATTERY_EMPTY, Create3Base
from tb4.sim.ui import Note

__all__ = ["Create3Services", "PRESS_TOPIC", "KIDNAP_TOPIC"]

PRESS_TOPIC = "tb4_sim/press_button"  # irobot_create_msgs/Button: header.frame_id names it, duration = hold time
KIDNAP_TOPIC = "tb4_sim/kidnap"  # geometry_msgs/PoseStamped in the map frame: where to put the robot down


class Create3Services:
    def __init__(
        self, node: Node, loop: LoopView, warn: Callable[[str, str], None], record: RobotRecord | None
    ) -> None:
        self.node = node
        self.loop = loop
        self.sim = loop.sim
        self.warn = warn
        self.record = record
        group = ReentrantCallbackGroup()
        create_service(node, ResetPose, "reset_pose", self._reset_pose, callback_group=group)
        create_service(node, EStop, "e_stop", self._e_stop, callback_group=group)
        create_service(node, RobotPower, "robot_power", self._robot_power, callback_group=group)
        # best effort accepts both kinds of publisher: the TurtleBot 4 manual's first node publishes sensor-data QoS
        node.create_subscription(LightringLeds, "cmd_lightring", self._lightring, qos_profile_sensor_data)
        # reliable, as on the Create 3 since G.4.4 / H.1.1 (a best-effort publisher does not reach it)
        node.create_subscription(AudioNoteVector, "cmd_audio", self._audio, RELIABLE)
        node.create_subscription(Button, PRESS_TOPIC, self._press, RELIABLE)
        node.create_subscription(PoseStamped, KIDNAP_TOPIC, self._kidnap, RELIABLE)
        self._battery_empty = False  # what the log last said (a robot started flat off its dock says so at once)
        self._battery_low = False
        loop.on_tick(self._report_power)

    @property
    def base(self) -> Create3Base:
        """The Create 3 base of the robot now (a world reset builds a new one)."""
        return self.sim.base

    def _refused(self, what: str, reason: str) -> None:
        """Logged at most once a second per kind of refusal: a flood of bad input does not flood the log."""
        self.warn(f"{what}:{reason[:30]}", f"{what} refused: {reason}")

    def _note(self, kind: str, **data: Any) -> None:
        if self.record is not None:
            self.record.note(kind, self.sim.time, **data)

    def _run(self, what: str, fn: Callable[[], Any], moves: bool = True) -> tuple[bool, str]:
        """Run `fn` in the loop (its changes to the world through the loop's inputs, or, for what cannot change
        any robot's motion, `moves=False`: outside the replay); a refusal is logged."""
        self.loop.release()
        try:
            if moves:
                self.loop.call(fn, timeout=5.0)
            else:
                self.loop.call_outside_replay(fn, what, moves=False, timeout=5.0)
        except (ValueError, TypeError) as exc:
            self._refused(what, str(exc))
            return False, str(exc)
        except Exception as exc:  # shutting down
            return False, f"{what} failed: {exc}"
        return True, ""

    # ------------------------------------------------------------------ services
    def _reset_pose(self, request: Any, response: Any) -> Any:
        try:
            x, y, yaw = checked_pose(request.pose, "reset_pose pose")
        except ValueError as exc:
            self._refused("reset_pose", str(exc))
            return response
        ok, _ = self._run("reset_pose", lambda: self.loop.inputs.sim.reset_odometry(x, y, yaw))
        if ok:
            self._note("reset_pose", pose=[round(x, 4), round(y, 4), round(yaw, 4)])
        return response

    def _e_stop(self, request: Any, response: Any) -> Any:
        on = bool(request.e_stop_on)

        def apply() -> None:
            self.loop.inputs.base.set_estop(on)
            if on:
                self.loop.inputs.sim.stop_motion("e-stop engaged")

        response.success, message = self._run("e_stop", apply)
        response.message = message or ("e-stop engaged: wheels disabled" if on else "e-stop released")
        self._note("e_stop", on=on)
        return response

    def _robot_power(self, request: Any, response: Any) -> Any:
        def apply() -> None:
            self.loop.inputs.base.power_off()
            self.loop.inputs.sim.stop_motion("the robot was powered off")

        response.success, message = self._run("robot_power", apply)
        response.message = message or "powering off: the robot wakes up when placed on its dock"
        self._note("robot_power")
        return response

    # ------------------------------------------------------------------ power
    def _report_power(self, now: float) -> None:
        """Each change of the battery's state, once (loop thread, every tick: two flags compared)."""
        base = self.base
        low = base.battery_low and not base.battery_empty and not self.sim.is_docked()  # on the dock it charges
        if low != self._battery_low:
            self._battery_low = low
            if low:
                level = 100.0 * self.sim.battery().percentage
                self.node.get_logger().warn(
                    f"battery low ({level:.1f} %, below {100 * LOW_LEVEL:.0f} %): the light ring pulses red; "
                    "dock to charge"
                )
                self._note("battery_low", percentage=round(level, 2))
        if base.battery_empty == self._battery_empty:
            return
        self._battery_empty = base.battery_empty
        if base.battery_empty:
            t = base.battery_empty_at if base.battery_empty_at is not None else now
            pose = self.sim.pose()
            self.node.get_logger().error(
                f"{BATTERY_EMPTY[0].upper()}{BATTERY_EMPTY[1:]} (t={t:.1f}s at ({pose.x:.2f}, {pose.y:.2f})); until "
                "then every drive and navigation goal fails"
            )
            if self.record is not None:
                self.record.note("battery_empty", t, x=round(pose.x, 3), y=round(pose.y, 3), message=BATTERY_EMPTY)
        else:
            self.node.get_logger().info("battery charging on the dock: the motors are enabled again")
            self._note("battery_charging")

    # ------------------------------------------------------------------ commands
    def _lightring(self, msg: LightringLeds) -> None:
        leds = [(c.red, c.green, c.blue) for c in msg.leds]
        override = bool(msg.override_system)
        ok, _ = self._run("cmd_lightring", lambda: self.base.lightring.command(leds, override), moves=False)
        if ok:
            self._note("lightring", leds=[list(c) for c in leds], override=override)

    def _audio(self, msg: AudioNoteVector) -> None:
        notes = [Note(int(n.frequency), duration_to_seconds(n.max_runtime)) for n in msg.notes]
        append = bool(msg.append)
        ok, _ = self._run("cmd_audio", lambda: self.base.speaker.command(notes, append, self.sim.time), moves=False)
        if ok:
            self._note("audio", notes=[[n.frequency, round(n.duration, 3)] for n in notes], append=append)

    def _press(self, msg: Button) -> None:
        name = msg.header.frame_id.rsplit("/", 1)[-1]
        duration = duration_to_seconds(msg.last_pressed_duration) or 0.2
        ok, _ = self._run("press", lambda: self.loop.inputs.base.press(name, duration, self.sim.time))
        if ok:
            self._note("button", button=name, duration=round(duration, 3))

    def _kidnap(self, msg: PoseStamped) -> None:
        try:
            if msg.header.frame_id not in ("", "map"):
                raise ValueError(f"kidnap pose must be in the map frame, got '{msg.header.frame_id}'")
            x, y, yaw = checked_pose(msg.pose, "kidnap pose")
        except ValueError as exc:
            self._refused("kidnap", str(exc))
            return
        ok, _ = self._run("kidnap", lambda: self.loop.inputs.sim.kidnap(x, y, yaw))
        if ok:
            self._note("kidnap", pose=[round(x, 4), round(y, 4), round(math.degrees(yaw), 2)])
