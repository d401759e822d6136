"""The Create 3's seven front IR proximity sensors and the dock's IR codes, from the distance field.

Each sensor sits on the bumper rim at its angle (robot.yaml `create3.ir_angles`) and looks outwards along it. The
reading is the Create 3's unitless intensity: `ir_max_intensity` at contact, falling off exponentially with the
distance to the nearest surface along the beam, 0 beyond `ir_range`. Deterministic: no noise.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from tb4.core.robot_params import Create3Params, DockParams
from tb4.sim.dock import dock_relative, dock_visible

__all__ = ["IR_FRAMES", "ir_distance", "ir_readings", "ir_opcodes", "FALLOFF"]

IR_FRAMES = (
    "ir_intensity_side_left",
    "ir_intensity_left",
    "ir_intensity_front_left",
    "ir_intensity_front_center_left",
    "ir_intensity_front_center_right",
    "ir_intensity_front_right",
    "ir_intensity_right",
)
FALLOFF = 0.05  # m: the intensity drops by e over this distance

# irobot_create_msgs/IrOpcode
_FORCE_FIELD, _BUOY_GREEN, _BUOY_RED, _BUOY_BOTH = 161, 164, 168, 172
SENSOR_OMNI, SENSOR_DIRECTIONAL_FRONT = 0, 1


def ir_distance(
    x: float, y: float, angle: float, clearance: Callable[[float, float], float], max_range: float
) -> float:
    """Distance along a beam from (x, y) at `angle` to the first surface (sphere tracing), inf beyond max_range."""
    dx, dy = math.cos(angle), math.sin(angle)
    t = 0.0
    while t <= max_range:
        c = clearance(x + t * dx, y + t * dy)
        if c <= 0.002:
            return t
        t += max(c, 0.002)
    return math.inf


def ir_readings(
    x: float, y: float, yaw: float, radius: float, clearance: Callable[[float, float], float], p: Create3Params
) -> list[int]:
    """Intensities of the 7 sensors, left to right."""
    out = []
    for deg in p.ir_angles:
        a = yaw + math.radians(deg)
        d = ir_distance(x + radius * math.cos(a), y + radius * math.sin(a), a, clearance, p.ir_range)
        out.append(0 if not math.isfinite(d) else int(round(p.ir_max_intensity * math.exp(-d / FALLOFF))))
    return out


def ir_opcodes(
    pose: tuple[float, float, float], dock: tuple[float, float, float], dp: DockParams, p: Create3Params
) -> list[tuple[int, int]]:
    """(opcode, sensor) pairs received from the dock: its force field close by, and its red/green buoys, which
    split the approach left/right of the dock axis (both near the axis), seen by the front directional sensor."""
    px, py, _ = dock_relative(pose, dock)
    dist = math.hypot(px, py)
    if dist > p.ir_opcode_distance or px > dp.docked_distance:
        return []
    out = []
    if dist < 0.3:
        out.append((_FORCE_FIELD, SENSOR_OMNI))
    if dock_visible(pose, dock, dp):
        code = _BUOY_BOTH if abs(py) < 0.05 else (_BUOY_GREEN if py > 0 else _BUOY_RED)
        out.append((code, SENSOR_DIRECTIONAL_FRONT))
    return out
