"""One robot of a fleet driven by an ordinary TurtleBot4Navigator in its namespace (a process of its own).

    fleet_drive.py /robot2 START_X START_Y GOAL_X GOAL_Y

Sets the initial pose at the start (facing north), waits for Nav2, undocks, drives to the goal; prints the result
and exits 0 when the goal was reached."""

from __future__ import annotations

import sys

import rclpy

from tb4.navigator import TaskResult, TurtleBot4Directions, TurtleBot4Navigator


def main(argv: list[str]) -> int:
    namespace = argv[0]
    start_x, start_y, goal_x, goal_y = (float(v) for v in argv[1:5])
    rclpy.init()
    navigator = TurtleBot4Navigator(namespace=namespace)
    try:
        navigator.setInitialPose(navigator.getPoseStamped([start_x, start_y], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startToPose(navigator.getPoseStamped([goal_x, goal_y], TurtleBot4Directions.SOUTH))
        result = navigator.getResult()
        print(f"fleet_drive {namespace}: {result.name}", flush=True)
        return 0 if result == TaskResult.SUCCEEDED else 1
    finally:
        navigator.destroyNode()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
