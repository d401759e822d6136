#!/usr/bin/env python3
"""Kilted style (our own script): follow three waypoints around the dock, watching the navigator's clock as Nav2's
waypoint example does (cancel after 600 s), then shut Nav2 down as it does. Upstream import paths only."""

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.duration import Duration

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

    navigator.setInitialPose(make_pose(navigator, 0.0, 0.0, 0.0))
    navigator.waitUntilNav2Active()

    undock_task = navigator.undockRobot()
    while not navigator.isTaskComplete(task=undock_task):
        pass

    goal_poses = [
        make_pose(navigator, -2.0, 0.0, 3.14),
        make_pose(navigator, -2.0, -2.0, 0.0),
        make_pose(navigator, -1.0, 1.0, -1.57),
    ]
    nav_start = navigator.get_clock().now()
    follow_waypoints_task = navigator.followWaypoints(goal_poses)

    i = 0
    seen = set()
    while not navigator.isTaskComplete(task=follow_waypoints_task):
        i = i + 1
        feedback = navigator.getFeedback(task=follow_waypoints_task)
        if feedback:
            seen.add(feedback.current_waypoint)
        if feedback and i % 5 == 0:
            print(f"Executing current waypoint: {feedback.current_waypoint + 1}/{len(goal_poses)}")
            if navigator.get_clock().now() - nav_start > Duration(seconds=600.0):
                navigator.cancelTask()

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
    print(f"Waypoints reported in feedback: {sorted(seen)}")

    navigator.lifecycleShutdown()  # as Nav2's examples end
    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if result == TaskResult.SUCCEEDED else 1)


if __name__ == "__main__":
    main()
