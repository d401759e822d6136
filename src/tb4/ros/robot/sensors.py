"""The Create 3's own sensor topics, published from the loop thread.

hazard_detection, ir_intensity, cliff_intensity, imu, mouse, wheel_vels, wheel_ticks and ir_opcode every control
tick (20 Hz sim time); kidnap_status, slip_status, stop_status and wheel_status at 1 Hz; interface_buttons on every
press and release; `tb4_sim/lightring` (what the ring shows) and `tb4_sim/audio` (the note sounding now, 0 Hz
when silent), for the viewer, on change and at 1 Hz. All reliable.
A topic nobody subscribes to is not serialized at all; each is bounded in wall rate, except that a change in the
hazards always goes out.
"""

from __future__ import annotations

from typing import Any

from irobot_create_msgs.msg import (
    AudioNote,
    Button,
    HazardDetection,
    HazardDetectionVector,
    InterfaceButtons,
    IrIntensity,
    IrIntensityVector,
    IrOpcode,
    KidnapStatus,
    LedColor,
    LightringLeds,
    Mouse,
    SlipStatus,
    StopStatus,
    WheelStatus,
    WheelTicks,
    WheelVels,
)
from rclpy.node import Node
from sensor_msgs.msg import Imu

from tb4.ros.convert import duration_msg, time_msg, yaw_to_quaternion
from tb4.ros.loop import LoopView
from tb4.ros.robot.common import RATES, RELIABLE, SENSOR_WALL_PERIOD, Throttle
from tb4.sim.create3 import Create3Base
from tb4.sim.hazards import BACKUP_LIMIT, CLIFF_FRAMES
from tb4.sim.ir import IR_FRAMES, ir_opcodes

__all__ = ["Create3Sensors"]

_INT16 = 32767


def _clamp_int(value: float, lo: int, hi: int) -> int:
    return int(max(lo, min(hi, round(value))))


class Create3Sensors:
    def __init__(self, node: Node, loop: LoopView, frames: dict[str, str], prefix: str, throttle: Throttle) -> None:
        self.loop = loop
        self.logger = node.get_logger()
        self.sim = loop.sim
        self.frames = frames
        self.prefix = prefix
        self._throttle = throttle
        pub = node.create_publisher
        self.pubs: dict[str, Any] = {
            "hazard_detection": pub(HazardDetectionVector, "hazard_detection", RELIABLE),
            "ir_intensity": pub(IrIntensityVector, "ir_intensity", RELIABLE),
            "cliff_intensity": pub(IrIntensityVector, "cliff_intensity", RELIABLE),
            "imu": pub(Imu, "imu", RELIABLE),
            "mouse": pub(Mouse, "mouse", RELIABLE),
            "wheel_vels": pub(WheelVels, "wheel_vels", RELIABLE),
            "wheel_ticks": pub(WheelTicks, "wheel_ticks", RELIABLE),
            "ir_opcode": pub(IrOpcode, "ir_opcode", RELIABLE),
            "kidnap_status": pub(KidnapStatus, "kidnap_status", RELIABLE),
            "slip_status": pub(SlipStatus, "slip_status", RELIABLE),
            "stop_status": pub(StopStatus, "stop_status", RELIABLE),
            "wheel_status": pub(WheelStatus, "wheel_status", RELIABLE),
            "interface_buttons": pub(InterfaceButtons, "interface_buttons", RELIABLE),
            "lightring": pub(LightringLeds, "tb4_sim/lightring", RELIABLE),
            "audio": pub(AudioNote, "tb4_sim/audio", RELIABLE),
        }
        self._hazard_key: tuple[Any, ...] = ()
        self._buttons_version = -1
        self._ring: tuple[Any, ...] = ()
        self._kidnapped = False
        self._slipping = False
        self._note = -1
        loop.every(RATES["fast"], self._publish_fast)
        loop.every(RATES["status"], self._publish_status)
        loop.on_tick(self._on_tick)

    @property
    def base(self) -> Create3Base:
        """The Create 3 base of the robot now (a world reset builds a new one)."""
        return self.sim.base

    def _wanted(self, topic: str, changed: bool = False) -> bool:
        # the wall-rate check first: asking DDS for the subscription count costs more, and at --rate max these
        # topics come due thousands of times a wall second
        if not changed and self._throttle.too_soon(topic, SENSOR_WALL_PERIOD):
            return False
        return self.pubs[topic].get_subscription_count() > 0

    def _header(self, msg: Any, now: float, frame: str = "base_link") -> Any:
        msg.header.stamp = time_msg(now)
        msg.header.frame_id = self.prefix + frame
        return msg

    # ------------------------------------------------------------------ every tick: changes
    def _on_tick(self, now: float) -> None:
        if self.base.buttons_version != self._buttons_version:
            self._buttons_version = self.base.buttons_version
            self._publish_buttons(now)
        ring = self.base.lightring.shown(now)
        if ring != self._ring and self._wanted("lightring"):  # an animation changes it 5 times a sim second
            self._ring = ring
            self._publish_lightring(now)
        note = self.base.speaker.playing(now)
        if note != self._note and self._wanted("audio"):
            self._publish_audio(now)
        if self.base.lifted != self._kidnapped:
            self._kidnapped = self.base.lifted
            self._publish_kidnap(now)
        slipping = bool(self.base.proprio.slipping)
        if slipping != self._slipping:  # a slip may last less than the 1 Hz status period: its start goes out
            self._slipping = slipping
            if self.pubs["slip_status"].get_subscription_count() > 0:
                self._publish_slip(now)

    def _publish_buttons(self, now: float) -> None:
        msg = self._header(InterfaceButtons(), now)
        for name, state in self.base.buttons.items():
            b = Button()
            b.header.stamp = time_msg(now)
            b.header.frame_id = self.prefix + name
            b.is_pressed = bool(state.is_pressed)
            b.last_start_pressed_time = time_msg(state.last_start)
            b.last_pressed_duration = duration_msg(state.last_duration)
            setattr(msg, name, b)
        self.pubs["interface_buttons"].publish(msg)

    def _publish_lightring(self, now: float) -> None:
        self._ring = self.base.lightring.shown(now)
        msg = self._header(LightringLeds(), now)
        msg.leds = [LedColor(red=r, green=g, blue=b) for r, g, b in self._ring]
        msg.override_system = bool(self.base.lightring.override)
        self.pubs["lightring"].publish(msg)

    def _publish_audio(self, now: float) -> None:
        self._note = self.base.speaker.playing(now)
        self.pubs["audio"].publish(AudioNote(frequency=max(0, min(65535, int(self._note)))))

    def _publish_slip(self, now: float) -> None:
        slipping = bool(self.base.proprio.slipping)
        self.pubs["slip_status"].publish(self._header(SlipStatus(is_slipping=slipping), now))

    def _publish_kidnap(self, now: float) -> None:
        self.pubs["kidnap_status"].publish(self._header(KidnapStatus(is_kidnapped=bool(self.base.lifted)), now))

    # ------------------------------------------------------------------ fast sensors
    def _publish_fast(self, now: float) -> None:
        hazards = self.base.hazards()
        key = tuple((h.type, h.frame) for h in hazards)
        changed = key != self._hazard_key
        if changed:
            new = {t for t, _ in key} - {t for t, _ in self._hazard_key}
            if BACKUP_LIMIT in new:  # the Create 3 warns in its log (and turns the ring orange)
                self.logger.warn("backup limit: the robot will not drive further backwards; drive forward first")
            self._hazard_key = key
        if self._wanted("hazard_detection", changed=changed):
            msg = self._header(HazardDetectionVector(), now)
            msg.detections = [self._header(HazardDetection(type=h.type), now, h.frame) for h in hazards]
            self.pubs["hazard_detection"].publish(msg)
        if self._wanted("ir_intensity"):
            self.pubs["ir_intensity"].publish(self._intensities(now, IR_FRAMES, self.base.ir(self.sim)))
        if self._wanted("cliff_intensity"):
            values = self.base.cliff_intensities(self.sim)
            self.pubs["cliff_intensity"].publish(self._intensities(now, CLIFF_FRAMES, values))
        pro = self.base.proprio
        if self._wanted("imu"):
            imu = pro.imu()
            msg = self._header(Imu(), now)
            msg.orientation = yaw_to_quaternion(imu.yaw)
            msg.angular_velocity.z = float(imu.angular_velocity_z)
            ax, ay, az = imu.linear_acceleration
            msg.linear_acceleration.x, msg.linear_acceleration.y, msg.linear_acceleration.z = ax, ay, az
            self.pubs["imu"].publish(msg)
        if self._wanted("mouse"):
            msg = self._header(Mouse(), now, "mouse")
            msg.integrated_x, msg.integrated_y = float(pro.mouse_x), float(pro.mouse_y)
            msg.frame_id = int(pro.mouse_frame) & 0xFFFFFFFF
            msg.last_squal = int(pro.mouse_quality)
            self.pubs["mouse"].publish(msg)
        if self._wanted("wheel_vels"):
            msg = self._header(WheelVels(), now)
            msg.velocity_left, msg.velocity_right = float(pro.left_rad_s), float(pro.right_rad_s)
            self.pubs["wheel_vels"].publish(msg)
        if self._wanted("wheel_ticks"):
            left, right = pro.ticks
            msg = self._header(WheelTicks(), now)
            msg.ticks_left, msg.ticks_right = _wrap_int32(left), _wrap_int32(right)
            self.pubs["wheel_ticks"].publish(msg)
        if self._wanted("ir_opcode"):
            dp = self.sim.params.dock
            for code, sensor in ir_opcodes(self._pose(), self.sim.dock_pose, dp, self.base.p):
                msg = self._header(IrOpcode(opcode=code, sensor=sensor), now, "ir_omni")
                self.pubs["ir_opcode"].publish(msg)

    def _pose(self) -> tuple[float, float, float]:
        p = self.sim.pose()
        return (p.x, p.y, p.yaw)

    def _intensities(self, now: float, frames: tuple[str, ...], values: list[int]) -> Any:
        msg = self._header(IrIntensityVector(), now)
        msg.readings = [
            self._header(IrIntensity(value=_clamp_int(v, -_INT16, _INT16)), now, f)
            for f, v in zip(frames, values, strict=False)
        ]
        return msg

    # ------------------------------------------------------------------ 1 Hz status
    def _publish_status(self, now: float) -> None:
        base, pro = self.base, self.base.proprio
        if self._wanted("kidnap_status"):
            self._publish_kidnap(now)
        if self._wanted("slip_status"):
            self._publish_slip(now)
        if self._wanted("stop_status"):
            v, w = self.sim.velocity()
            stopped = abs(v) < 1e-3 and abs(w) < 1e-3
            self.pubs["stop_status"].publish(self._header(StopStatus(is_stopped=stopped), now))
        if self._wanted("wheel_status"):
            msg = self._header(WheelStatus(), now)
            top = self.sim.params.drive.max_linear_speed / base.p.wheel_radius  # rad/s at full speed
            for side, rate in (("left", pro.left_rad_s), ("right", pro.right_rad_s)):
                stalled = base.stall > 0.0
                setattr(msg, f"pwm_{side}", _clamp_int(_INT16 * (1.0 if stalled else rate / top), -_INT16, _INT16))
                setattr(
                    msg, f"current_ma_{side}", _clamp_int(40.0 * abs(rate) + (600.0 if stalled else 0.0), 0, _INT16)
                )
            msg.wheels_enabled = not base.refuse_motion()
            self.pubs["wheel_status"].publish(msg)
        if self._wanted("lightring"):
            self._publish_lightring(now)
        if self._wanted("audio"):
            self._publish_audio(now)


def _wrap_int32(value: int) -> int:
    return (int(value) + 2**31) % 2**32 - 2**31
