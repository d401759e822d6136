#!/usr/bin/env python3
"""Record a path with RViz's '2D Pose Estimate' tool, then follow it (rewrite of the create_path tutorial)."""

import rclpy

from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator


def main():
    rclpy.init()

    navigator = TurtleBot4Navigator()

    # Set goal poses
    goal_pose = navigator.createPath()

    if len(goal_pose) == 0:
        navigator.error("No poses were given, exiting.")
        exit(0)

    # Start on dock
    if not navigator.getDockedStatus():
        navigator.info("Docking before intialising pose")
        navigator.dock()

    # Clear any poses that were set by the path creation
    navigator.clearAllCostmaps()

    # Set initial pose
    initial_pose = navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH)
    navigator.setInitialPose(initial_pose)

    # Wait for Nav2
    navigator.waitUntilNav2Active()

    # Undock
    navigator.undock()

    # Follow Waypoints
    navigator.startFollowWaypoints(goal_pose)

    # Finished navigating, dock
    navigator.dock()

    rclpy.shutdown()


if __name__ == "__main__":
    main()
