"""The TurtleBot 4 user manual's first Python node, as a user writes it: button 1 on the Create 3 toggles the
light ring. (Our own code following the manual's pattern: subscribe interface_buttons with the sensor-data
profile, publish cmd_lightring on each new press.)"""

from __future__ import annotations

import sys

import rclpy
from irobot_create_msgs.msg import InterfaceButtons, LedColor, LightringLeds
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data


class TurtleBot4FirstNode(Node):
    def __init__(self) -> None:
        super().__init__("turtlebot4_first_python_node")
        self.create_subscription(InterfaceButtons, "interface_buttons", self.on_buttons, qos_profile_sensor_data)
        self.lightring_publisher = self.create_publisher(LightringLeds, "cmd_lightring", qos_profile_sensor_data)
        self.lights_on = False
        self.was_pressed = False
        print("first node ready", flush=True)

    def on_buttons(self, msg: InterfaceButtons) -> None:
        pressed = msg.button_1.is_pressed
        if pressed and not self.was_pressed:
            self.button_1_function()
        self.was_pressed = pressed

    def button_1_function(self) -> None:
        self.lights_on = not self.lights_on
        colour = LedColor(red=255, green=255, blue=255) if self.lights_on else LedColor()
        msg = LightringLeds(override_system=True, leds=[colour] * 6)
        self.lightring_publisher.publish(msg)
        print(f"lights {'on' if self.lights_on else 'off'}", flush=True)


def main() -> int:
    rclpy.init()
    node = TurtleBot4FirstNode()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
