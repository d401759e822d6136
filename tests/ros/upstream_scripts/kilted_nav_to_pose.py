#!/usr/bin/env python3
"""Kilted style (our own script): undock with Nav2's docking server, navigate to a pose inside the warehouse, then
to one far outside the map, which must fail with Nav2's error code (not an exception).

Written the way Nav2's Kilted examples are: every task method returns a RunningTask that isTaskComplete(task=...)
and getFeedback(task=...) take. Upstream import paths only.
"""

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


def drive(navigator, task, label):
    i = 0
    while not navigator.isTaskComplete(task=task):
        i += 1
        feedback = navigator.getFeedback(task=task)
        if feedback and i % 5 == 0:
            eta = Duration.from_msg(feedback.estimated_time_remaining).nanoseconds / 1e9
            print(f"Estimated time of arrival at {label}: {eta:.0f} seconds.")
    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED:
        print(f"Goal {label} succeeded!")
    elif result == TaskResult.CANCELED:
        print(f"Goal {label} was canceled!")
    elif result == TaskResult.FAILED:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Goal {label} failed!{error_code}:{error_msg}")
    else:
        print(f"Goal {label} has an invalid return status!")
    return result


def main():
    rclpy.init()
    navigator = BasicNavigator()

    navigator.setInitialPose(make_pose(navigator, 0.0, 0.0, 0.0))
    navigator.waitUntilNav2Active()

    undock_task = navigator.undockRobot()
    while not navigator.isTaskComplete(task=undock_task):
        pass
    print(f"Undock: {navigator.getResult()}")

    inside = drive(navigator, navigator.goToPose(make_pose(navigator, -13.0, 9.0, 1.57)), "inside")
    outside = drive(navigator, navigator.goToPose(make_pose(navigator, 500.0, -400.0, 0.0)), "outside")
    print(f"Results: inside={inside.name} outside={outside.name}")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if inside == TaskResult.SUCCEEDED and outside == TaskResult.FAILED else 1)


if __name__ == "__main__":
    main()
