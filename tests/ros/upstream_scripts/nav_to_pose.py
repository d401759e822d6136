#!/usr/bin/env python3
"""Navigate to one pose across the warehouse (our rewrite of the TurtleBot 4 nav_to_pose tutorial).

Uses only the upstream import paths, so it runs unchanged on a robot with turtlebot4_navigation installed.
"""

import rclpy

from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator


def main():
    rclpy.init()

    navigator = TurtleBot4Navigator()

    # Start on dock
    if not navigator.getDockedStatus():
        navigator.info("Docking before intialising pose")
        navigator.dock()

    # Set initial pose
    initial_pose = navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH)
    navigator.setInitialPose(initial_pose)

    # Wait for Nav2
    navigator.waitUntilNav2Active()

    # Set goal pose
    goal_pose = navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST)

    # Undock
    navigator.undock()

    # Go to goal pose
    navigator.startToPose(goal_pose)

    rclpy.shutdown()


if __name__ == "__main__":
    main()
