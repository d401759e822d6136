#!/usr/bin/env python3
"""Kilted style (our own script): plan a path, smooth it, and hand it to the controller with followPath, printing
the controller's feedback. Upstream import paths only; RunningTask handles as Nav2's Kilted examples use them."""

import rclpy
from geometry_msgs.msg import PoseStamped

from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult
from nav2_simple_commander.utils import euler_to_quaternion


def make_pose(navigator, x, y, yaw):
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.header.stamp = navigator.get_clock().now().to_msg()
    pose.pose.position.x = x
    pose.pose.position.y = y
    pose.pose.orientation = euler_to_quaternion(0.0, 0.0, yaw)
    return pose


def main():
    rclpy.init()
    navigator = BasicNavigator()

    initial_pose = make_pose(navigator, 0.0, 0.0, 0.0)
    navigator.setInitialPose(initial_pose)
    navigator.waitUntilNav2Active()

    undock_task = navigator.undockRobot()
    while not navigator.isTaskComplete(task=undock_task):
        pass

    goal_pose = make_pose(navigator, -2.0, -2.0, 0.0)
    path = navigator.getPath(initial_pose, goal_pose)
    print(f"Planned {len(path.poses)} poses")
    smoothed_path = navigator.smoothPath(path)
    print(f"Smoothed to {len(smoothed_path.poses)} poses")

    follow_path_task = navigator.followPath(smoothed_path)
    i = 0
    while not navigator.isTaskComplete(task=follow_path_task):
        i += 1
        feedback = navigator.getFeedback(task=follow_path_task)
        if feedback and i % 5 == 0:
            print(
                "Estimated distance remaining to goal position: "
                + f"{feedback.distance_to_goal:.3f}"
                + "\nCurrent speed of the robot: "
                + f"{feedback.speed:.3f}"
            )

    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        print("Goal succeeded!")
    elif result == TaskResult.CANCELED:
        print("Goal was canceled!")
    elif result == TaskResult.FAILED:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Goal failed!{error_code}:{error_msg}")
    else:
        print("Goal has an invalid return status!")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if result == TaskResult.SUCCEEDED else 1)


if __name__ == "__main__":
    main()
