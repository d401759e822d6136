#!/usr/bin/env python3
"""Jazzy/Humble style (our own script): the call style Nav2's examples had before Kilted, run on the same navigator.
Task methods are tested for truth, isTaskComplete()/getFeedback() take no task, goThroughPoses takes a list."""

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.duration import Duration

from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult


def make_pose(navigator, x, y, z, w):
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.header.stamp = navigator.get_clock().now().to_msg()
    pose.pose.position.x = x
    pose.pose.position.y = y
    pose.pose.orientation.z = z
    pose.pose.orientation.w = w
    return pose


def main():
    rclpy.init()
    navigator = BasicNavigator()
    navigator.setInitialPose(make_pose(navigator, 0.0, 0.0, 0.0, 1.0))
    navigator.waitUntilNav2Active()

    goal_poses = [make_pose(navigator, -2.0, 0.0, 1.0, 0.0), make_pose(navigator, -2.0, -2.0, 0.0, 1.0)]
    path = navigator.getPathThroughPoses(goal_poses[0], goal_poses)
    print(f"Path through {len(goal_poses)} poses: {len(path.poses)} poses")

    if not navigator.goThroughPoses(goal_poses):
        print("Goal was rejected!")
        exit(1)
    i = 0
    while not navigator.isTaskComplete():
        i += 1
        feedback = navigator.getFeedback()
        if feedback and i % 5 == 0:
            eta = Duration.from_msg(feedback.estimated_time_remaining).nanoseconds / 1e9
            print(f"Estimated time of arrival: {eta:.0f} seconds.")
    through = navigator.getResult()
    print(f"Through poses: {through}")

    navigator.followWaypoints([make_pose(navigator, -1.0, 1.0, 0.0, 1.0)])
    while not navigator.isTaskComplete():
        pass
    waypoints = navigator.getResult()
    print(f"Waypoints: {waypoints}")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if through == waypoints == TaskResult.SUCCEEDED else 1)


if __name__ == "__main__":
    main()
