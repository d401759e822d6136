#!/usr/bin/env python3
"""Kilted style (our own script), after Nav2's picking demo: fetch an item at a shelf of the warehouse, then bring it
to a shipping destination through a checkpoint, given as a nav_msgs/Goals (Kilted's goThroughPoses type)."""

import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Goals
from rclpy.duration import Duration

from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult
from nav2_simple_commander.utils import euler_to_quaternion

# Shelf positions for picking: x, y, heading (radians)
shelf_positions = {
    "shelf_A": [-12.8, -5.0, 3.14],
    "shelf_B": [-13.0, 9.0, 1.57],
}

# Shipping destinations, reached through a checkpoint on the open floor
shipping_destinations = {
    "loading_bay": [[-2.0, -2.0, -1.57], [2.0, -23.0, 0.0]],
    "home": [[-2.0, 0.0, 0.0], [-1.0, 1.0, -1.57]],
}


def make_pose(navigator, x, y, yaw):
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.header.stamp = navigator.get_clock().now().to_msg()
    pose.pose.position.x = x
    pose.pose.position.y = y
    pose.pose.orientation = euler_to_quaternion(0.0, 0.0, yaw)
    return pose


def main():
    request_item_location = "shelf_A"
    request_destination = "home"

    rclpy.init()
    navigator = BasicNavigator()
    navigator.setInitialPose(make_pose(navigator, 0.0, 0.0, 0.0))
    navigator.waitUntilNav2Active()
    undock_task = navigator.undockRobot()
    while not navigator.isTaskComplete(task=undock_task):
        pass

    print(f"Received request for item picking at {request_item_location}.")
    go_to_pose_task = navigator.goToPose(make_pose(navigator, *shelf_positions[request_item_location]))

    i = 0
    while not navigator.isTaskComplete(task=go_to_pose_task):
        i += 1
        feedback = navigator.getFeedback(task=go_to_pose_task)
        if feedback and i % 5 == 0:
            eta = Duration.from_msg(feedback.estimated_time_remaining).nanoseconds / 1e9
            print(f"Estimated time of arrival at {request_item_location} for worker: {eta:.0f} seconds.")

    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        print(
            f"Got product from {request_item_location}! "
            f"Bringing product to shipping destination ({request_destination})..."
        )
        goals = Goals()
        goals.header.frame_id = "map"
        goals.header.stamp = navigator.get_clock().now().to_msg()
        goals.goals = [make_pose(navigator, *p) for p in shipping_destinations[request_destination]]
        shipping_task = navigator.goThroughPoses(goals)
    elif result == TaskResult.CANCELED:
        print(f"Task at {request_item_location} was canceled. Returning to staging point...")
        exit(1)
    else:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Task at {request_item_location} failed!:{error_code}:{error_msg}")
        exit(1)

    while not navigator.isTaskComplete(task=shipping_task):
        pass
    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        print(f"Product delivered to {request_destination}!")
    else:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Delivery to {request_destination} failed!:{error_code}:{error_msg}")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if result == TaskResult.SUCCEEDED else 1)


if __name__ == "__main__":
    main()
