"""Patrol four poses around the warehouse; when the battery runs low, go home, dock, charge to 95 %, resume.

The battery is watched by a second node in its own thread, as upstream does. Without a limit the patrol goes on
until Ctrl-C; `--laps N` or `--sim-hours H` end it after that much patrolling.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections.abc import Sequence
from typing import Any

from tb4.tutorials.common import close_navigator, open_navigator, pose_from_table, sim_sleep, start_on_dock

__all__ = ["WORLD", "main", "PATROL", "HOME", "BATTERY_HIGH", "BATTERY_LOW", "BATTERY_CRITICAL", "BatteryMonitor"]
WORLD = "warehouse"
BATTERY_HIGH = 0.95
BATTERY_LOW = 0.2
BATTERY_CRITICAL = 0.1
HOME = ((-1.0, 1.0), "EAST")
PATROL = (
    ((-5.0, 1.0), "EAST"),
    ((-5.0, -23.0), "NORTH"),
    ((9.0, -23.0), "NORTH_WEST"),
    ((10.0, 2.0), "WEST"),
)
CHARGE_STEP = 15.0  # s of (sim) time between charging checks


class BatteryMonitor:
    """A node of its own, spun in its own thread, that keeps the latest battery percentage."""

    def __init__(self, namespace: str = "") -> None:
        from rclpy.qos import qos_profile_sensor_data
        from sensor_msgs.msg import BatteryState

        from tb4.ros.background import BackgroundNode

        # battery_state comes once a sim second: hundreds a wall second at --rate max, dispatched from C++
        self._background = BackgroundNode("battery_monitor", namespace, events_executor=True)
        self.node = self._background.node
        self._lock = threading.Lock()
        self._percent: float | None = None
        self._arrived = threading.Event()
        self.node.create_subscription(BatteryState, "battery_state", self._on_battery, qos_profile_sensor_data)
        self._background.start()

    def _on_battery(self, msg: Any) -> None:
        with self._lock:
            self._percent = float(msg.percentage)
        self._arrived.set()

    def percent(self, timeout: float = 10.0) -> float:
        if not self._arrived.wait(timeout):
            raise TimeoutError(f"no message on 'battery_state' after {timeout:g} s: is the robot (or simulator) up?")
        with self._lock:
            assert self._percent is not None
            return self._percent

    def close(self) -> None:
        self._background.close()


def _arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--namespace", default="")
    parser.add_argument("--laps", type=int, default=None, help="stop after this many full patrol laps")
    parser.add_argument("--sim-hours", type=float, default=None, help="stop after this many hours of (sim) time")
    args = parser.parse_known_args(argv)[0]
    if args.laps is not None and args.laps < 1:
        parser.error("--laps must be at least 1")
    if args.sim_hours is not None and not args.sim_hours > 0:
        parser.error("--sim-hours must be positive")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = _arguments(argv)
    navigator = open_navigator(args.namespace)
    battery = BatteryMonitor(args.namespace)
    try:
        return _patrol(navigator, battery, args)
    except KeyboardInterrupt:
        navigator.info("Patrol stopped by the user.")
        navigator.cancelTask()
        return 0
    finally:
        battery.close()
        close_navigator(navigator)


def _patrol(navigator: Any, battery: BatteryMonitor, args: argparse.Namespace) -> int:
    from tb4.navigator import TaskResult

    def pose(entry: tuple[tuple[float, float], str]) -> Any:
        return pose_from_table(navigator, entry)

    start_on_dock(navigator)
    started = navigator.get_clock().now().nanoseconds
    position_index = 0
    laps = 0
    while True:
        if args.sim_hours is not None and navigator.get_clock().now().nanoseconds - started >= args.sim_hours * 3.6e12:
            navigator.info(f"Patrolled for {args.sim_hours:g} h: done.")
            return 0
        percent = battery.percent()
        if percent < BATTERY_CRITICAL:
            navigator.error("Battery critically low. Charge or power down")
            return 1
        if percent < BATTERY_LOW:
            navigator.info("Docking for charge")
            navigator.startToPose(pose(HOME))
            navigator.dock()
            if not navigator.getDockedStatus():
                navigator.error("Robot failed to dock")
                return 1
            logged = -1
            while (percent := battery.percent()) < BATTERY_HIGH:
                if int(100 * percent) > logged:  # one line per percent gained
                    logged = int(100 * percent)
                    navigator.info(f"Charging... battery at {logged}%")
                sim_sleep(navigator, CHARGE_STEP)
            navigator.info(f"Charged to {100 * percent:.0f}%: resuming the patrol")
            navigator.undock()
            position_index = 0
            continue
        navigator.startToPose(pose(PATROL[position_index]))
        if navigator.getResult() != TaskResult.SUCCEEDED:
            navigator.warn(f"Could not reach patrol pose {position_index}; going on to the next one")
        position_index = (position_index + 1) % len(PATROL)
        if position_index == 0:
            laps += 1
            navigator.info(f"Patrol lap {laps} done")
            if args.laps is not None and laps >= args.laps:
                return 0


if __name__ == "__main__":
    sys.exit(main())
