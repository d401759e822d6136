"""The Create 3 base around the drive: safety (e-stop, power, backup limit, cliffs), hazards, kidnap, buttons,
light ring and speaker, and the proprioceptive sensors. Owned and stepped by Simulation every physics step.

`gate` runs before a step moves the robot (what the safety rules let the wheels do), `after_move` after it (what
the sensors saw, which goals must abort). Safety follows create3_docs: `safety_override` none / backup_only / full,
and every built-in behaviour runs with all safety features on whatever the override.

Power: below 10 % the light ring pulses red (create3_docs hw/face.md); at 0 % off the dock the motors stop
(BATTERY_EMPTY, `battery_empty`) until the dock charges the pack again. Simulation reports the battery here after
every step (`set_battery`).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING

from tb4.core.robot_params import RobotParams
from tb4.sim.hazards import (
    BACKUP_LIMIT,
    BUMP,
    CLIFF,
    STALL,
    WHEEL_DROP,
    BackupLimit,
    CliffMap,
    Hazard,
    bump_frame,
    cliff_points,
    contact_angle,
    wheel_points,
)
from tb4.sim.ir import IR_FRAMES, ir_distance, ir_readings
from tb4.sim.proprio import Proprioception
from tb4.sim.ui import BUTTONS, OFF, ORANGE, WHITE, ButtonState, Color, Lightring, Speaker

if TYPE_CHECKING:
    from tb4.sim.simulation import Simulation

__all__ = ["SAFETY_OVERRIDES", "BATTERY_EMPTY", "Create3Base", "IR_FRAMES"]

SAFETY_OVERRIDES = ("none", "backup_only", "full")
MAX_PRESS = 60.0  # s a button can be held by `tb4 press`
STALL_REPORT = 0.5  # s hazard_detection keeps a STALL after the wheels stopped pushing
#: why nothing drives once the pack is flat off the dock: drive goals, cmd_vel and every navigation goal end with it
BATTERY_EMPTY = "the battery is empty (0 %): the Create 3 stopped its motors; put the robot on its dock to charge"
RED: Color = (255, 0, 0)
LOW_BATTERY_PULSE = 1.0  # s: one period of the low-battery pulse (red, then dark)


class Create3Base:
    """State of the base that is not the drive itself; see the module docstring."""

    def __init__(self, params: RobotParams, cliffs: Sequence[object] = ()) -> None:
        self.params = params
        self.p = params.create3
        self.backup = BackupLimit(self.p)
        self.proprio = Proprioception(self.p)
        self.cliffs = CliffMap(cliffs)
        self._reach = max(self.p.cliff_radius, 0.5 * self.p.wheel_base) + 0.05  # sensors' distance from the centre
        self._cliff_far = (0.0, 0.0, -1.0)  # (x, y, margin): no cliff within reach while within margin of (x, y)
        self.lightring = Lightring()
        self.speaker = Speaker()
        self.buttons = {name: ButtonState() for name in BUTTONS}
        self.buttons_version = 0  # bumped on every press and release (interface_buttons goes out on change)
        self._held = False  # some button is down
        self.estop = False
        self.powered = True
        self.battery_empty = False  # flat off the dock: the motors stopped (set_battery)
        self.battery_empty_at: float | None = None  # sim time the pack last ran flat
        self.battery_low = False  # below LOW_LEVEL: the light ring pulses red
        self.safety_override = "none"
        self.lifted = False
        self._place: tuple[float, tuple[float, float, float]] | None = None  # (sim time, pose) of a kidnap
        self.stall = 0.0  # s pushing against an obstacle without moving
        self.stalled_until = -math.inf  # a stall is reported for STALL_REPORT s (the goal it aborts stops the push)
        self._contact: tuple[float, float, float, float] | None = None  # pose and time of the bumper's contact
        self._bump: tuple[tuple[float, float, float, float], str] | None = None  # (contact, zone) found last
        self._sim: Simulation | None = None
        self.cliff_frames: tuple[str, ...] = ()
        self.dropped: tuple[str, ...] = ()
        self.events: deque[tuple[float, str]] = deque(maxlen=500)  # what a person did or the robot refused
        self._backup_braked = False
        self._now = 0.0

    # ------------------------------------------------------------------ person inputs
    def set_estop(self, on: bool) -> None:
        """The e_stop service: engaged, the wheels stay disabled until it is released."""
        self.estop = bool(on)

    def power_off(self) -> None:
        """The robot_power service: off until the robot is placed on its dock."""
        self.powered = False

    def set_safety_override(self, value: str) -> None:
        if value not in SAFETY_OVERRIDES:
            raise ValueError(f"safety_override must be one of {', '.join(SAFETY_OVERRIDES)}, got {value!r}")
        self.safety_override = value

    def press(self, button: str, duration: float, now: float) -> None:
        """A person presses `button` for `duration` seconds."""
        if button not in self.buttons:
            raise ValueError(f"unknown button {button!r}: use one of {', '.join(BUTTONS)}")
        if not (math.isfinite(duration) and 0.0 < duration <= MAX_PRESS):
            raise ValueError(f"press duration must be within (0, {MAX_PRESS:g}] s, got {duration!r}")
        b = self.buttons[button]
        if b.is_pressed:
            b.last_duration = now - b.last_start
        b.is_pressed, b.last_start, b.release_at = True, now, now + duration
        self._held = True
        self.buttons_version += 1
        self.events.append((now, f"press {button} {duration:g}s"))

    def _release_buttons(self, now: float) -> None:
        for b in self.buttons.values():
            if b.is_pressed and now >= b.release_at - 1e-9:
                b.is_pressed, b.last_duration = False, b.release_at - b.last_start
                self.buttons_version += 1
        self._held = any(b.is_pressed for b in self.buttons.values())

    def kidnap(self, pose: tuple[float, float, float], now: float) -> None:
        """Lift the robot now; it is put down at `pose` after `kidnap_lift_time`."""
        self.lifted = True
        self._place = (now + self.p.kidnap_lift_time, pose)
        self.backup.kidnapped()
        self.proprio.lost_tracking()
        self.events.append((now, f"kidnap to ({pose[0]:.2f}, {pose[1]:.2f}, {math.degrees(pose[2]):.0f} deg)"))

    def set_battery(self, empty: bool, low: bool, now: float) -> bool:
        """What the pack reads after a step (Simulation calls it after every one).

        Args:
            empty: flat and off the dock (on the dock the dock powers the robot).
            low: below tb4.sim.battery.LOW_LEVEL (the light ring pulses red).
            now: sim time of the step.

        Returns:
            True when the pack has just run flat: the caller stops whatever drives.
        """
        self.battery_low = low
        if empty == self.battery_empty:
            return False
        self.battery_empty = empty
        if empty:
            self.battery_empty_at = now
            self.events.append((now, "battery empty: motors stopped"))
        else:
            self.events.append((now, "battery charging: motors enabled"))
        return empty

    def refuse_motion(self) -> str:
        """Why the wheels cannot be commanded now ('' when they can)."""
        if self.battery_empty:
            return BATTERY_EMPTY
        return self._refusal()

    def _refusal(self) -> str:
        """refuse_motion's reasons but the battery's."""
        if not self.powered:
            return "the robot is powered off (robot_power); put it on its dock to wake it"
        if self.estop:
            return "e-stop engaged"
        if self.lifted:
            return "the robot is lifted (kidnapped)"
        if self.dropped:
            return "a wheel dropped off a cliff"
        return ""

    # ------------------------------------------------------------------ stepping
    def gate(self, sim: Simulation, v: float, w: float, builtin: bool, exempt: bool) -> tuple[float, float, str]:
        """Velocities the safety rules allow this step, and the rule that stopped the robot ('' if none)."""
        if self.refuse_motion():
            return (0.0, 0.0, self.refuse_motion())
        override = "none" if builtin else self.safety_override
        if v < 0.0 and not exempt and override == "none" and not self.backup.allows(v):
            self._backup_braked = True
            return (0.0, 0.0, "backup limit reached")
        if v > 0.0 and override != "full" and self.cliff_frames:
            return (0.0, 0.0, "cliff ahead")
        return (v, w, "")

    def after_move(
        self,
        sim: Simulation,
        before: tuple[float, float, float],
        after: tuple[float, float, float],
        v: float,
        w: float,
        dt: float,
        blocked: bool,
        exempt: bool = False,
    ) -> str:
        """Update sensors and hazards after a step; returns why a running drive goal must abort ('' if not).
        `exempt`: the dock actions, whose reversing off the dock does not use up the backup allowance."""
        now = self._now = sim.time
        if self._held:
            self._release_buttons(now)
        if self._place is not None and now >= self._place[0] - 1e-9:
            pose = self._place[1]
            self._place = None
            # In the air only the gyro notices anything: the fused odometry turns with the robot, the wheels and
            # the mouse saw no travel, so the position stays where it was lifted.
            turn = math.remainder(pose[2] - sim.yaw, 2.0 * math.pi)
            sim.turn_odometry(turn)
            self.proprio.gyro_yaw = math.remainder(self.proprio.gyro_yaw + turn, 2.0 * math.pi)
            sim.set_pose(*pose)
            self.lifted = False
            self.dropped = ()
            after = pose
            before = pose
        dx, dy = after[0] - before[0], after[1] - before[1]
        moved = dx * math.cos(before[2]) + dy * math.sin(before[2])
        turned = math.remainder(after[2] - before[2], 2.0 * math.pi)
        if not exempt:
            self.backup.travel(moved)
        if moved > 0.0:
            self._backup_braked = False
        self.proprio.update(v, w, moved, turned, dt, self.lifted)
        x, y, yaw = after
        if not self.powered and sim.is_docked():
            self.powered = True
            self.events.append((now, "powered on by the dock"))
        self.stall = self.stall + dt if blocked else 0.0
        if self.stall >= self.p.stall_time:
            self.stalled_until = now + STALL_REPORT
        self._contact = (x, y, yaw, now) if sim.in_contact and not self.lifted else None
        self._sim = sim
        if self.lifted:
            self.cliff_frames = tuple(f for f, _, _ in cliff_points(x, y, yaw, self.p))
        elif self.cliffs and self._near_cliff(x, y):
            self.cliff_frames = tuple(f for f, cx, cy in cliff_points(x, y, yaw, self.p) if self.cliffs.over(cx, cy))
            self.dropped = self.dropped or tuple(
                f for f, wx, wy in wheel_points(x, y, yaw, self.p) if self.cliffs.over(wx, wy)
            )
        elif self.cliff_frames:
            self.cliff_frames = ()
        self.lightring.system = self._system_color(now)
        animation = self.lightring.animation
        if animation is not None:
            animation.step(now)
        if self.speaker.sequence is not None:
            self.speaker.sequence.step(now)
        refused = self.refuse_motion()
        if refused:
            return refused
        if self.cliff_frames:
            return f"cliff detected by {', '.join(self.cliff_frames)}"
        if self.stall >= self.p.stall_time:
            return f"wheels stalled against an obstacle for {self.p.stall_time:g} s"
        return ""

    def at_rest(self) -> bool:
        """Whether a physics step of a still robot changes nothing here but the clock: no button, kidnap, animation
        or sound is timed, nothing refuses motion (a dock would power the robot on), no stall or contact, and the
        sensors read still. A flat battery does not count: Simulation takes the steps where it changes alone."""
        animation, sequence = self.lightring.animation, self.speaker.sequence
        return (
            not self._held
            and self._place is None
            and (animation is None or animation.done)
            and (sequence is None or sequence.done)
            and self.stall == 0.0
            and self._contact is None
            and not self._refusal()
            and self.proprio.at_rest()
        )

    def rest(self, now: float, steps: int) -> None:
        """What `after_move` does over `steps` still steps (at_rest() held, the robot not moved since), ending at
        sim time `now`."""
        self._now = now
        self.proprio.rest(steps)
        self.lightring.system = self._system_color(now)

    def _system_color(self, now: float) -> Color:
        """The light ring's own pattern: orange while the backup limit is reported, pulsing red on a low battery
        (the Create 3's "place on charger"), else white."""
        if self._backup_reported():
            return ORANGE
        if self.battery_low:
            return RED if now % LOW_BATTERY_PULSE < 0.5 * LOW_BATTERY_PULSE else OFF
        return WHITE

    def _near_cliff(self, x: float, y: float) -> bool:
        """Whether a sensor may be over a cliff; far from every cliff the answer holds until the robot has moved
        by that margin, so open-floor steps cost one hypot."""
        fx, fy, margin = self._cliff_far
        if math.hypot(x - fx, y - fy) < margin:
            return False
        gap = self.cliffs.gap(x, y) - self._reach
        if gap <= 0.0:
            return True
        self._cliff_far = (x, y, gap)
        return False

    @property
    def bump(self) -> str | None:
        """Bumper zone pressed now (None: not pressed). Found by probing around the footprint, only when asked
        (the sensors publish at 20 Hz; physics steps at 100 Hz), and again only when the contact moved."""
        contact, sim = self._contact, self._sim
        if contact is None or sim is None:
            return None
        if self._bump is not None and self._bump[0][:3] == contact[:3] and not sim.has_moving_obstacles:
            return self._bump[1]
        zone = bump_frame(contact_angle(*contact[:3], sim.clearance_at, sim.params.drive.radius))
        self._bump = (contact, zone)
        return zone

    def _backup_reported(self) -> bool:
        return self.safety_override == "none" and (self.backup.reported or self._backup_braked)

    # ------------------------------------------------------------------ readings
    def hazards(self) -> list[Hazard]:
        """What hazard_detection carries now (empty: nothing detected)."""
        out: list[Hazard] = []
        if self._backup_reported():
            out.append(Hazard(BACKUP_LIMIT, "base_link"))
        bump = self.bump
        if bump is not None:
            out.append(Hazard(BUMP, bump))
        out.extend(Hazard(CLIFF, f) for f in self.cliff_frames)
        if self.stall >= self.p.stall_time or self._now < self.stalled_until:
            out.append(Hazard(STALL, "base_link"))
        dropped = ("wheel_drop_left", "wheel_drop_right") if self.lifted else self.dropped
        out.extend(Hazard(WHEEL_DROP, f) for f in dropped)
        return out

    def ir(self, sim: Simulation) -> list[int]:
        if self.lifted:
            return [0] * len(self.p.ir_angles)
        x, y, yaw = sim.x, sim.y, sim.yaw
        return ir_readings(x, y, yaw, sim.params.drive.radius, sim.clearance_at, self.p)

    def side_ranges(self, sim: Simulation, side: int) -> tuple[float, float, float]:
        """(front, diagonal, lateral) IR beam distances on one side (+1 left, -1 right), for wall following."""
        r = sim.params.drive.radius
        out = []
        for deg in (side * 10.0, side * 45.0, side * 80.0):
            a = sim.yaw + math.radians(deg)
            px, py = sim.x + r * math.cos(a), sim.y + r * math.sin(a)
            out.append(ir_distance(px, py, a, sim.clearance_at, 0.5))
        return (out[0], out[1], out[2])

    def cliff_intensities(self, sim: Simulation) -> list[int]:
        """Cliff sensors' IR return: bright floor (about 2000), near 0 over a drop or in the air."""
        pts = cliff_points(sim.x, sim.y, sim.yaw, self.p)
        return [5 if (self.lifted or (self.cliffs and self.cliffs.over(cx, cy))) else 2000 for _, cx, cy in pts]
