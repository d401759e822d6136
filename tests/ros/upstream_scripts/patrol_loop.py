#!/usr/bin/env python3
"""Patrol four poses, docking to charge when the battery runs low (rewrite of the patrol_loop tutorial).

PATROL_LAPS=N ends the patrol after N laps (the tutorial patrols forever); the tests set it to 1.
"""

import os
from threading import Lock, Thread
from time import sleep

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import BatteryState

from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

BATTERY_HIGH = 0.95
BATTERY_LOW = 0.2  # when the robot will go charge
BATTERY_CRITICAL = 0.1  # when the robot will shutdown

battery_percent = None


class BatteryMonitor(Node):
    def __init__(self, lock):
        super().__init__("battery_monitor")

        self.lock = lock

        # Subscribe to the /battery_state topic
        self.battery_state_subscriber = self.create_subscription(
            BatteryState, "battery_state", self.battery_state_callback, qos_profile_sensor_data
        )

    # Callbacks
    def battery_state_callback(self, batt_msg: BatteryState):
        with self.lock:
            global battery_percent
            battery_percent = batt_msg.percentage

    def thread_function(self):
        executor = SingleThreadedExecutor()
        executor.add_node(self)
        executor.spin()


def main(args=None):
    rclpy.init(args=args)

    lock = Lock()
    battery_monitor = BatteryMonitor(lock=lock)

    navigator = TurtleBot4Navigator()
    battery_percent_prev = 0
    laps = int(os.environ.get("PATROL_LAPS", "0"))  # 0: forever, like the tutorial
    laps_done = 0
    position_index = 0

    thread = Thread(target=battery_monitor.thread_function, daemon=True)
    thread.start()

    # Start on dock
    if not navigator.getDockedStatus():
        navigator.info("Docking before intialising pose")
        navigator.dock()

    # Set initial pose
    initial_pose = navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH)
    navigator.setInitialPose(initial_pose)

    # Wait for Nav2
    navigator.waitUntilNav2Active()

    # Undock
    navigator.undock()

    # Prepare goal poses
    goal_pose = []
    goal_pose.append(navigator.getPoseStamped([-5.0, 1.0], TurtleBot4Directions.EAST))
    goal_pose.append(navigator.getPoseStamped([-5.0, -23.0], TurtleBot4Directions.NORTH))
    goal_pose.append(navigator.getPoseStamped([9.0, -23.0], TurtleBot4Directions.NORTH_WEST))
    goal_pose.append(navigator.getPoseStamped([10.0, 2.0], TurtleBot4Directions.WEST))

    while True:
        with lock:
            percent = battery_percent
        if percent is None:
            sleep(0.1)  # no battery state yet
            continue

        navigator.info(f"Battery is at {(percent * 100):.2f}% charge")

        # Check battery charge level
        if percent < BATTERY_CRITICAL:
            navigator.error("Battery critically low. Charge or power down")
            break
        elif percent < BATTERY_LOW:
            # Go near the dock
            navigator.info("Docking for charge")
            navigator.startToPose(navigator.getPoseStamped([-1.0, 1.0], TurtleBot4Directions.EAST))
            navigator.dock()

            if not navigator.getDockedStatus():
                navigator.error("Robot failed to dock")
                break

            # Wait until charged
            navigator.info("Charging...")
            battery_percent_prev = 0
            while True:
                with lock:
                    percent = battery_percent
                if percent >= BATTERY_HIGH:
                    break
                sleep(15)
                if int(percent * 100) > int(battery_percent_prev * 100):
                    navigator.info(f"Battery is at {(percent * 100):.2f}% charge")
                    battery_percent_prev = percent

            # Undock
            navigator.undock()
            position_index = 0

        else:
            # Navigate to next position
            navigator.startToPose(goal_pose[position_index])

            position_index = position_index + 1
            if position_index >= len(goal_pose):
                position_index = 0
                laps_done += 1
                if laps and laps_done >= laps:
                    navigator.info(f"Patrol finished after {laps_done} lap(s)")
                    break

    rclpy.shutdown()  # ends the battery monitor's spin
    thread.join(timeout=5.0)


if __name__ == "__main__":
    main()
