"""The robot side of the simulator, as a TurtleBot 4 (Create 3 base + RPLIDAR) presents it over ROS 2.

One module per job in tb4.ros.robot: `topics` (clock, odom, tf, scan, battery, dock status, cmd_vel),
`sensors` (the Create 3's hazard, IR, IMU, mouse, wheel, status and button topics), `actions` (dock, undock, drive
goals, light and audio goals), `services` (reset_pose, e_stop, robot_power, cmd_lightring, cmd_audio and the
person inputs) and `safety` (the motion_control node's safety_override). The physics is in tb4.sim (no ROS).
"""

from __future__ import annotations

from rclpy.node import Node

from tb4.ros.loop import LoopView
from tb4.ros.robot.actions import Create3Actions
from tb4.ros.robot.common import FRAMES, RATES, Throttle
from tb4.ros.robot.safety import MotionControl
from tb4.ros.robot.sensors import Create3Sensors
from tb4.ros.robot.services import KIDNAP_TOPIC, PRESS_TOPIC, Create3Services
from tb4.ros.robot.topics import RobotTopics
from tb4.ros.run_record import RobotRecord

__all__ = ["Create3Interfaces", "RATES", "FRAMES", "PRESS_TOPIC", "KIDNAP_TOPIC"]


class Create3Interfaces:
    """Everything the Create 3 serves, on `node` (plus the motion_control node in the same namespace)."""

    def __init__(
        self,
        node: Node,
        loop: LoopView,
        frame_prefix: str = "",
        record: RobotRecord | None = None,
        clock: bool = True,
    ) -> None:
        """`clock`: publish /clock (a fleet's first robot does, the others do not: one clock per process)."""
        throttle = Throttle()
        frames = {k: frame_prefix + v for k, v in FRAMES.items()}
        self.topics = RobotTopics(node, loop, frames, throttle, clock, record)
        self.actions = Create3Actions(node, loop, frames, record)
        self.sensors = Create3Sensors(node, loop, frames, frame_prefix, throttle)
        self.services = Create3Services(node, loop, self.topics.warn_limited, record)
        self.motion_control = MotionControl(node.context, loop, node.get_namespace())

    @property
    def bumps(self) -> int:
        return self.topics.bumps

    @property
    def warnings(self) -> int:
        return self.topics.warnings

    def nodes(self) -> list[Node]:
        """Nodes besides the robot node that the executor must spin."""
        return [self.motion_control.node]
