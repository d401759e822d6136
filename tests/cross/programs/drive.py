"""A navigator's session across ROS 2 distributions, run by one environment's Python against a simulator on another's:
undock (Create 3), navigate to a pose, through poses and along waypoints (Nav2), dock again (Create 3). Prints one
JSON line per step ({"step", "result", "detail"}) and exits 0 only when every step succeeded; the simulator is left
docked for the next session on it."""

from __future__ import annotations

import json
import sys

import rclpy

from tb4.rosenv import installed_middleware
from tb4.wire import wire_format
from turtlebot4_navigation.turtlebot4_navigator import TaskResult, TurtleBot4Directions, TurtleBot4Navigator


def report(step: str, ok: bool, detail: str = "") -> bool:
    print(json.dumps({"step": step, "result": "succeeded" if ok else "failed", "detail": detail}), flush=True)
    return ok


def main() -> int:
    middleware = installed_middleware()
    print(json.dumps({"middleware": middleware.describe(), "wire_format": wire_format()}), flush=True)
    rclpy.init()
    navigator = TurtleBot4Navigator()
    ok = True
    try:
        if not navigator.getDockedStatus():
            ok &= report("dock before starting", navigator.dock())
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        ok &= report("undock", navigator.undock())

        result = navigator.startToPose(navigator.getPoseStamped([-1.0, 1.0], TurtleBot4Directions.WEST))
        ok &= report("navigate_to_pose", result == TaskResult.SUCCEEDED, str(result))

        through = [
            navigator.getPoseStamped([-2.0, 0.0], TurtleBot4Directions.SOUTH),
            navigator.getPoseStamped([-1.0, -1.0], TurtleBot4Directions.EAST),
        ]
        result = navigator.startThroughPoses(through)
        ok &= report("navigate_through_poses", result == TaskResult.SUCCEEDED, str(result))

        # the last one a metre behind the dock, facing it (the warehouse's dock is at the origin, facing north):
        # where the Create 3's dock action sees it
        waypoints = [
            navigator.getPoseStamped([-2.0, 1.0], TurtleBot4Directions.EAST),
            navigator.getPoseStamped([-1.0, 0.0], TurtleBot4Directions.NORTH),
        ]
        result = navigator.startFollowWaypoints(waypoints)
        ok &= report("follow_waypoints", result == TaskResult.SUCCEEDED, str(result))

        ok &= report("dock", navigator.dock())
    finally:
        navigator.destroyNode()
        rclpy.try_shutdown()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
