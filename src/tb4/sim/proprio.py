"""What the Create 3 feels of its own motion: wheel speeds and encoder ticks, IMU, optical mouse, slip and stop.

Derived each physics step from the motion actually executed (after ramps, bumps and safety stops), so a robot
pushing against a wall has stopped wheels and a blocked mouse, and a lifted robot moves nothing. Ticks follow the
Create 3's 508.8 ticks per wheel revolution (robot.yaml `create3.ticks_per_rev`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from tb4.core.geometry import rewrap, wrap_angle
from tb4.core.robot_params import Create3Params

__all__ = ["GRAVITY", "ImuReading", "Proprioception"]

GRAVITY = 9.80665


@dataclass(frozen=True)
class ImuReading:
    yaw: float  # integrated gyro heading since start (rad)
    angular_velocity_z: float  # rad/s
    linear_acceleration: tuple[float, float, float]  # m/s^2 in the robot frame, gravity on +z


class Proprioception:
    """Integrates wheel ticks, mouse displacement and the gyro from each executed step."""

    def __init__(self, p: Create3Params) -> None:
        self.p = p
        self.left_rad_s = self.right_rad_s = 0.0
        self._ticks_left = self._ticks_right = 0.0
        self.mouse_x = self.mouse_y = 0.0
        self.mouse_frame = 0  # incremented each time the mouse loses tracking (lifted)
        self.mouse_quality = 60
        self.gyro_yaw = 0.0
        self.w = 0.0
        self.accel = (0.0, 0.0, GRAVITY)
        self._v = 0.0
        self.slipping = False
        self.pushing = False

    def update(self, wheel_v: float, wheel_w: float, moved: float, turned: float, dt: float, lifted: bool) -> None:
        """`wheel_v, wheel_w`: body speeds the wheels turn at; `moved, turned`: the body's actual motion."""
        p = self.p
        half = 0.5 * p.wheel_base
        vl, vr = wheel_v - wheel_w * half, wheel_v + wheel_w * half
        self.left_rad_s, self.right_rad_s = vl / p.wheel_radius, vr / p.wheel_radius
        per_rad = p.ticks_per_rev / (2.0 * math.pi)
        self._ticks_left += self.left_rad_s * dt * per_rad
        self._ticks_right += self.right_rad_s * dt * per_rad
        if lifted:
            self.mouse_quality = 0
            self.w = 0.0
            self.accel = (0.0, 0.0, GRAVITY)
            self._v = 0.0
            return
        self.mouse_quality = 60
        self.mouse_x += moved
        v = moved / dt if dt > 0 else 0.0
        self.w = turned / dt if dt > 0 else 0.0
        self.gyro_yaw = wrap_angle(self.gyro_yaw + turned)
        ax = (v - self._v) / dt if dt > 0 else 0.0
        self.accel = (ax, v * self.w, GRAVITY)
        self._v = v
        # the wheels turn but the body does not follow: slipping (pushing a wall, or a wheel in the air)
        self.slipping = abs(wheel_v) > 1e-3 and abs(moved) < 0.1 * abs(wheel_v) * dt

    def at_rest(self) -> bool:
        """Whether the last step left every reading as a still robot's: another still step changes only the gyro's
        last bits (its heading is wrapped again)."""
        return (
            self.left_rad_s == 0.0
            and self.right_rad_s == 0.0
            and self._v == 0.0
            and self.w == 0.0
            and self.accel == (0.0, 0.0, GRAVITY)
            and self.mouse_quality == 60
            and not self.slipping
        )

    def rest(self, steps: int) -> None:
        """`steps` physics steps of a still robot (at_rest() held), the same to the last bit as `update`."""
        self.gyro_yaw = rewrap(self.gyro_yaw, steps)

    def lost_tracking(self) -> None:
        self.mouse_frame += 1

    @property
    def ticks(self) -> tuple[int, int]:
        return (int(math.floor(self._ticks_left)), int(math.floor(self._ticks_right)))

    def imu(self) -> ImuReading:
        return ImuReading(self.gyro_yaw, self.w, self.accel)
