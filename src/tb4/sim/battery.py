"""The Create 3 battery: a 26 Wh 4S Li-ion pack drained by a base load plus motion, charged on the dock.

Energy is tracked in watt-hours and every update is exact for constant power, so the model can be stepped with
any dt (a whole hour at once in tests). With the defaults a robot idles ~4.3 h, patrols (driving 60 % of the
time at 0.26 m/s) ~3.2 h, drives flat out ~2.5 h, and charges from empty to full in 2.5 h.

The Create 3 reports 0 % at 12.0 V, and its pack disconnects itself from any load at 10.8 V; the light ring flashes
red from about 10 % (create3_docs: hw/electrical.md, hw/face.md). The model's capacity is what lies between 0 % and
100 %, so the robot stops at 0 % (tb4.sim.create3.BATTERY_EMPTY), and LOW_LEVEL marks the light ring's warning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tb4.core.robot_params import BatteryParams

__all__ = [
    "LOW_LEVEL",
    "POWER_SUPPLY_STATUS_UNKNOWN",
    "POWER_SUPPLY_STATUS_CHARGING",
    "POWER_SUPPLY_STATUS_DISCHARGING",
    "POWER_SUPPLY_STATUS_NOT_CHARGING",
    "POWER_SUPPLY_STATUS_FULL",
    "BatteryStatus",
    "Battery",
]

# sensor_msgs/BatteryState power_supply_status values
POWER_SUPPLY_STATUS_UNKNOWN = 0
POWER_SUPPLY_STATUS_CHARGING = 1
POWER_SUPPLY_STATUS_DISCHARGING = 2
POWER_SUPPLY_STATUS_NOT_CHARGING = 3
POWER_SUPPLY_STATUS_FULL = 4

LOW_LEVEL = 0.10  # below this the Create 3's light ring pulses red: "place on charger"

# Open-circuit voltage against state of charge (fractions of the empty..full span): flat in the middle,
# steep at both ends, like a Li-ion cell; 14.4 V nominal sits near 45 %.
_SOC = np.array([0.0, 0.05, 0.1, 0.2, 0.5, 0.8, 0.9, 1.0])
_OCV = np.array([0.0, 0.25, 0.33, 0.42, 0.55, 0.72, 0.83, 1.0])


@dataclass(frozen=True)
class BatteryStatus:
    """What sensor_msgs/BatteryState carries for the Create 3 (current < 0 while discharging)."""

    percentage: float  # 0..1
    voltage: float  # V
    current: float  # A
    charge: float  # Ah
    capacity: float  # Ah
    design_capacity: float  # Ah
    power_supply_status: int
    temperature: float  # deg C


class Battery:
    """Energy bookkeeping of the pack; `update` is exact for constant (v, w) over dt."""

    def __init__(self, params: BatteryParams, level: float = 1.0) -> None:
        if not 0.0 <= level <= 1.0:
            raise ValueError(f"battery level must be within 0..1, got {level}")
        self.params = params
        self.energy_wh = level * params.capacity_wh
        self.power = params.base_power  # W, positive = drawn from the pack, negative = charging
        self.charging = False

    @property
    def level(self) -> float:
        return self.energy_wh / self.params.capacity_wh

    @property
    def empty(self) -> bool:
        return self.energy_wh <= 0.0

    @property
    def full(self) -> bool:
        return self.energy_wh >= self.params.capacity_wh

    @property
    def low(self) -> bool:
        """Below LOW_LEVEL: the Create 3 warns with its light ring."""
        return self.energy_wh < LOW_LEVEL * self.params.capacity_wh

    def rest_steps_before_empty(self, dt: float) -> float:
        """How many still steps off the dock surely leave some charge.

        Two steps short of the quotient: `rest` subtracts step by step, and its rounding must not take the step the
        pack runs out into a span of steps taken together (Simulation takes that step alone).

        Args:
            dt: the step, in seconds.

        Returns:
            A whole number of steps, or inf when none is drawn or the pack is empty already.
        """
        loss = self.load_power(0.0, 0.0) * dt / 3600.0
        if loss <= 0.0 or self.energy_wh <= 0.0:
            return float("inf")
        return max(0.0, float(int(self.energy_wh / loss)) - 2.0)

    def load_power(self, v: float, w: float) -> float:
        """Power (W) drawn by the robot driving at (v, w)."""
        p = self.params
        return p.base_power + p.linear_power * abs(v) + p.angular_power * abs(w)

    @property
    def charge_power(self) -> float:
        """Net power (W) into the pack on the dock: empty to full in `charge_time` hours."""
        return self.params.capacity_wh / self.params.charge_time

    def update(self, dt: float, v: float = 0.0, w: float = 0.0, docked: bool = False) -> None:
        """Advance dt seconds: charge when docked (the dock also feeds the robot), else drain.

        The power is taken as constant over dt, so one call with dt = 3600 equals 360000 calls with dt = 0.01.
        """
        cap = self.params.capacity_wh
        self.charging = docked
        if docked:
            self.energy_wh = min(cap, self.energy_wh + self.charge_power * dt / 3600.0)
            self.power = 0.0 if self.energy_wh >= cap else -self.charge_power
        else:
            self.power = self.load_power(v, w)
            self.energy_wh = max(0.0, self.energy_wh - self.power * dt / 3600.0)
            if self.energy_wh <= 0.0:
                self.power = 0.0  # flat: the robot has shut down

    def rest(self, dt: float, steps: int, docked: bool) -> None:
        """`steps` calls of update(dt) for a still robot, the same to the last bit (the sum is taken step by step)."""
        if steps <= 0:
            return
        energy, cap = self.energy_wh, self.params.capacity_wh
        if docked:
            gain = self.charge_power * dt / 3600.0
            for _ in range(steps):
                if energy >= cap:
                    break
                energy = min(cap, energy + gain)
        else:
            loss = self.load_power(0.0, 0.0) * dt / 3600.0
            for _ in range(steps):
                if energy <= 0.0:
                    break
                energy = max(0.0, energy - loss)
        self.energy_wh = energy
        self.update(0.0, 0.0, 0.0, docked)  # power and charging flag as the last step leaves them

    def voltage(self) -> float:
        p = self.params
        frac = float(np.interp(self.level, _SOC, _OCV))
        return p.empty_voltage + frac * (p.full_voltage - p.empty_voltage)

    def status(self) -> BatteryStatus:
        p = self.params
        volts = self.voltage()
        if self.charging:
            code = POWER_SUPPLY_STATUS_FULL if self.full else POWER_SUPPLY_STATUS_CHARGING
        else:
            code = POWER_SUPPLY_STATUS_NOT_CHARGING if self.empty else POWER_SUPPLY_STATUS_DISCHARGING
        return BatteryStatus(
            percentage=self.level,
            voltage=volts,
            current=0.0 - self.power / volts,
            charge=self.level * p.capacity_ah,
            capacity=p.capacity_ah,
            design_capacity=p.capacity_ah,
            power_supply_status=code,
            temperature=p.temperature,
        )
