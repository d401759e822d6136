"""The Create 3's face in the viewer: what the light ring shows, the note playing, which buttons are held, the
hazards, and the page's buttons that press the robot's (through the simulator's `tb4_sim/press_button` input)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from irobot_create_msgs.msg import AudioNote, Button, HazardDetectionVector, InterfaceButtons, LightringLeds
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from tb4.ros.convert import duration_msg
from tb4.ros.robot.services import PRESS_TOPIC

__all__ = ["Create3Panel", "BUTTONS", "HAZARD_NAMES"]

BUTTONS = ("button_1", "button_power", "button_2")
HAZARD_NAMES = {0: "backup limit", 1: "bump", 2: "cliff", 3: "stall", 4: "wheel drop", 5: "proximity"}
_SENSOR = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)


class Create3Panel:
    """Subscribes with `subscribe(type, topic, callback, qos)` (the bridge's guarded subscription) and writes
    plain values into the viewer state's `create3` dict."""

    def __init__(self, node: Node, state: Any, subscribe: Callable[..., None]) -> None:
        self.state = state
        subscribe(LightringLeds, "tb4_sim/lightring", self._on_ring, _SENSOR)
        subscribe(InterfaceButtons, "interface_buttons", self._on_buttons, _SENSOR)
        subscribe(HazardDetectionVector, "hazard_detection", self._on_hazards, _SENSOR)
        subscribe(AudioNote, "tb4_sim/audio", self._on_audio, _SENSOR)
        self.press_pub = node.create_publisher(Button, PRESS_TOPIC, 10)

    def _on_ring(self, msg: LightringLeds) -> None:
        leds = [[int(c.red), int(c.green), int(c.blue)] for c in msg.leds]
        self.state.set_create3("lightring", {"leds": leds, "override": bool(msg.override_system)})

    def _on_audio(self, msg: AudioNote) -> None:
        self.state.set_create3("audio_hz", int(msg.frequency))

    def _on_buttons(self, msg: InterfaceButtons) -> None:
        self.state.set_create3("buttons", {name: bool(getattr(msg, name).is_pressed) for name in BUTTONS})

    def _on_hazards(self, msg: HazardDetectionVector) -> None:
        hazards = sorted(
            {f"{HAZARD_NAMES.get(d.type, d.type)} ({d.header.frame_id.rsplit('/', 1)[-1]})" for d in msg.detections}
        )
        self.state.set_create3("hazards", hazards)

    def press(self, button: str, hold: float = 0.3) -> str:
        if button not in BUTTONS:
            raise ValueError(f"unknown button {button!r}")
        if self.press_pub.get_subscription_count() == 0:
            raise RuntimeError("nothing takes button presses here (only `tb4 sim` does)")
        msg = Button(is_pressed=True, last_pressed_duration=duration_msg(hold))
        msg.header.frame_id = button
        self.press_pub.publish(msg)
        return f"pressed {button}"
