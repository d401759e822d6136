#!/usr/bin/env python3
"""Kilted style (our own script), after Nav2's inspection demo: visit inspection points along the racks with the
waypoint follower (one of them outside the map: it is missed, the others still inspected), then return to the
start. Upstream import paths only."""

import rclpy
from geometry_msgs.msg import PoseStamped

from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult
from nav2_simple_commander.utils import euler_to_quaternion

# Inspection points: x, y, heading (radians); the third is far outside the warehouse map.
inspection_route = [
    [-2.0, 0.0, 3.14],
    [-2.0, -2.0, -1.57],
    [250.0, 250.0, 0.0],
    [-1.0, 1.0, 1.57],
]


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

    inspection_points = [make_pose(navigator, *pt) for pt in inspection_route]
    wpf_task = navigator.followWaypoints(inspection_points)

    i = 0
    while not navigator.isTaskComplete(task=wpf_task):
        i += 1
        feedback = navigator.getFeedback(task=wpf_task)
        if feedback and i % 5 == 0:
            print(f"Executing current waypoint: {feedback.current_waypoint + 1}/{len(inspection_points)}")

    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        missed = [w.waypoint_index for w in navigator.result_future.result().result.missed_waypoints]
        print(f"Inspection of shelves complete! Missed waypoints: {missed}. Returning to start...")
    elif result == TaskResult.CANCELED:
        print("Inspection of shelving was canceled. Returning to start...")
    elif result == TaskResult.FAILED:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Inspection of shelving failed!:{error_code}:{error_msg}")
        print("Returning to start...")

    initial_pose.header.stamp = navigator.get_clock().now().to_msg()
    go_to_pose_task = navigator.goToPose(initial_pose)
    while not navigator.isTaskComplete(task=go_to_pose_task):
        pass
    back = navigator.getResult()
    print(f"Back at the start: {back.name}")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if back == TaskResult.SUCCEEDED else 1)


if __name__ == "__main__":
    main()
