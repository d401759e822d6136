"""The `motion_control` node's parameters, as on a Create 3: `safety_override` (none, backup_only, full) and the
read-only `max_speed`. A typo in the value is rejected by the parameter service, as on the robot."""

from __future__ import annotations

from functools import partial
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.context import Context

from tb4.ros.loop import LoopView
from tb4.ros.sim_node import SimNode
from tb4.sim.create3 import SAFETY_OVERRIDES

__all__ = ["MotionControl"]


class MotionControl:
    def __init__(self, context: Context, loop: LoopView, namespace: str) -> None:
        self.loop = loop
        self.node = SimNode("motion_control", namespace=namespace or "/", context=context)
        self.node.declare_parameter(
            "safety_override",
            loop.sim.base.safety_override,
            ParameterDescriptor(description=f"one of {', '.join(SAFETY_OVERRIDES)}"),
        )
        self.node.declare_parameter(
            "max_speed", float(loop.sim.params.drive.max_linear_speed), ParameterDescriptor(read_only=True)
        )
        self.node.add_on_set_parameters_callback(self._on_set)

    def _on_set(self, params: list[Any]) -> SetParametersResult:
        for p in params:
            if p.name != "safety_override":
                continue
            value = p.value
            if value not in SAFETY_OVERRIDES:
                return SetParametersResult(
                    successful=False, reason=f"safety_override must be one of {', '.join(SAFETY_OVERRIDES)}"
                )
            # validated above, so it cannot fail in the loop: hand it over without blocking the parameter service
            self.loop.submit(partial(self.loop.inputs.base.set_safety_override, str(value)))
        return SetParametersResult(successful=True)
