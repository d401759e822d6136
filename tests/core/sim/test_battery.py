"""Battery runtimes and charge time against the TurtleBot 4 figures (26 Wh, 2.5-4 h, ~2.5 h charge)."""

from __future__ import annotations

import dataclasses

import pytest

from tb4.core.robot_params import default_robot_params
from tb4.sim.battery import (
    POWER_SUPPLY_STATUS_CHARGING,
    POWER_SUPPLY_STATUS_DISCHARGING,
    POWER_SUPPLY_STATUS_FULL,
    POWER_SUPPLY_STATUS_NOT_CHARGING,
    Battery,
)

pytestmark = pytest.mark.core

PARAMS = default_robot_params().battery


def hours_until_empty(battery: Battery, duty: float, v: float, w: float = 0.0, period: float = 100.0) -> float:
    """Drive `duty` of each period at (v, w), idle the rest, until flat (big steps: the model is exact)."""
    t = 0.0
    while not battery.empty:
        battery.update(duty * period, v, w)
        battery.update((1 - duty) * period)
        t += period
        assert t < 24 * 3600
    return t / 3600.0


def test_idle_runtime_is_at_most_about_4_5_hours() -> None:
    hours = hours_until_empty(Battery(PARAMS), 0.0, 0.0)
    assert 3.5 < hours <= 4.5


def test_patrol_runtime_is_between_2_5_and_4_hours() -> None:
    hours = hours_until_empty(Battery(PARAMS), 0.6, 0.26, 0.1)
    assert 2.5 <= hours <= 4.0


def test_driving_flat_out_drains_faster_than_idling() -> None:
    flat_out = hours_until_empty(Battery(PARAMS), 1.0, 0.31, 0.5)
    assert 2.0 < flat_out < hours_until_empty(Battery(PARAMS), 0.6, 0.26)


def test_empty_to_full_on_the_dock_in_about_2_5_hours() -> None:
    battery = Battery(PARAMS, level=0.0)
    minutes = 0
    statuses = set()
    while not battery.full:
        battery.update(60.0, docked=True)
        statuses.add(battery.status().power_supply_status)
        minutes += 1
        assert minutes < 600
    assert minutes == pytest.approx(150, abs=2)
    assert POWER_SUPPLY_STATUS_CHARGING in statuses
    assert battery.status().power_supply_status == POWER_SUPPLY_STATUS_FULL
    assert battery.status().current == 0.0


def test_big_steps_equal_small_steps() -> None:
    a, b = Battery(PARAMS), Battery(PARAMS)
    a.update(1800.0, 0.2, 0.3)
    for _ in range(1800):
        b.update(1.0, 0.2, 0.3)
    assert a.level == pytest.approx(b.level, abs=1e-9)


def test_status_fields() -> None:
    battery = Battery(PARAMS, level=0.5)
    battery.update(1.0, 0.3, 0.0)
    s = battery.status()
    assert s.power_supply_status == POWER_SUPPLY_STATUS_DISCHARGING
    assert s.capacity == s.design_capacity == pytest.approx(26.0 / 14.4)
    assert s.charge == pytest.approx(s.percentage * s.capacity)
    assert s.current < 0.0
    assert s.current == pytest.approx(-battery.load_power(0.3, 0.0) / s.voltage)
    assert 12.0 < s.voltage < 16.8
    assert s.temperature == PARAMS.temperature
    battery.update(1.0, docked=True)
    assert battery.status().power_supply_status == POWER_SUPPLY_STATUS_CHARGING
    assert battery.status().current > 0.0


def test_voltage_follows_state_of_charge() -> None:
    levels = [i / 20 for i in range(21)]
    volts = [Battery(PARAMS, level=x).voltage() for x in levels]
    assert volts[0] == pytest.approx(12.0) and volts[-1] == pytest.approx(16.8)
    assert all(a < b for a, b in zip(volts, volts[1:], strict=False))
    assert 14.0 < Battery(PARAMS, level=0.45).voltage() < 14.8  # ~nominal 14.4 V mid-pack


def test_empty_battery_shuts_down() -> None:
    battery = Battery(PARAMS, level=0.001)
    battery.update(3600.0, 0.3, 0.0)
    assert battery.empty and battery.level == 0.0
    s = battery.status()
    assert s.power_supply_status == POWER_SUPPLY_STATUS_NOT_CHARGING and s.current == 0.0


def test_configurable_capacity_and_start_level() -> None:
    small = dataclasses.replace(PARAMS, capacity_wh=13.0)
    assert hours_until_empty(Battery(small), 0.0, 0.0) == pytest.approx(
        hours_until_empty(Battery(PARAMS), 0.0, 0.0) / 2, abs=0.03
    )
    assert Battery(PARAMS, level=0.3).status().percentage == pytest.approx(0.3)
    with pytest.raises(ValueError):
        Battery(PARAMS, level=1.5)


@pytest.mark.parametrize(("level", "docked"), [(0.9999, True), (0.18, True), (0.0001, False), (0.5, False)])
def test_rest_is_update_step_by_step_to_the_last_bit(level: float, docked: bool) -> None:
    stepped, rested = Battery(PARAMS, level), Battery(PARAMS, level)
    for chunk in (1, 7, 50_000, 3):
        for _ in range(chunk):
            stepped.update(0.01, 0.0, 0.0, docked)
        rested.rest(0.01, chunk, docked)
        assert (rested.energy_wh, rested.power, rested.charging) == (stepped.energy_wh, stepped.power, stepped.charging)
    if level > 0.99:
        assert stepped.full  # the chunks ran past full...
    if level < 0.001:
        assert stepped.empty  # ...and past empty
