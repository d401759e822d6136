#!/usr/bin/env python3
"""Kilted style (our own script), after Nav2's recoveries demo: drive into an aisle, back up, spin around, drive
on the heading, an assisted-teleop window handed back with cancelTask, then return. Feedback is printed."""

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


def report(navigator, what):
    result = navigator.getResult()
    if result == TaskResult.FAILED:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"{what} failed!:{error_code}:{error_msg}")
    else:
        print(f"{what}: {result.name}")
    return result


def main():
    rclpy.init()
    navigator = BasicNavigator()

    navigator.setInitialPose(make_pose(navigator, 0.0, 0.0, 0.0))
    navigator.waitUntilNav2Active()
    undock_task = navigator.undockRobot()
    while not navigator.isTaskComplete(task=undock_task):
        pass

    go_to_pose_task = navigator.goToPose(make_pose(navigator, -3.0, 0.0, 3.14))
    i = 0
    while not navigator.isTaskComplete(task=go_to_pose_task):
        i += 1
        feedback = navigator.getFeedback(task=go_to_pose_task)
        if feedback and i % 5 == 0:
            eta = Duration.from_msg(feedback.estimated_time_remaining).nanoseconds / 1e9
            print(f"Estimated time of arrival to destination is: {eta}")
    results = [report(navigator, "Drive to the aisle")]

    print("Robot hit a dead end (let's pretend), backing up...")
    # 0.3 m: the Create 3 reverses no farther than its backup limit (0.5 m, safety_override none), and with
    # odometry slip a 0.5 m backup can need a little more than that
    backup_task = navigator.backup(backup_dist=0.3, backup_speed=0.1)
    i = 0
    while not navigator.isTaskComplete(task=backup_task):
        i += 1
        feedback = navigator.getFeedback(task=backup_task)
        if feedback and i % 5 == 0:
            print(f"Distance traveled: {feedback.distance_traveled:.2f}")
    results.append(report(navigator, "Backup"))

    print("Spinning robot around...")
    spin_task = navigator.spin(spin_dist=3.14)
    i = 0
    while not navigator.isTaskComplete(task=spin_task):
        i += 1
        feedback = navigator.getFeedback(task=spin_task)
        if feedback and i % 5 == 0:
            print(f"Spin angle traveled: {feedback.angular_distance_traveled:.2f}")
    results.append(report(navigator, "Spin"))

    drive_task = navigator.driveOnHeading(dist=0.5, speed=0.2)
    i = 0
    while not navigator.isTaskComplete(task=drive_task):
        i += 1
        feedback = navigator.getFeedback(task=drive_task)
        if feedback and i % 5 == 0:
            print(f"Distance driven: {feedback.distance_traveled:.2f}")
    results.append(report(navigator, "Drive on heading"))

    # Assisted teleop runs until canceled (or fails when its time allowance runs out): hand control back after
    # one second of teleop, as the server counts it in its feedback.
    teleop_task = navigator.assistedTeleop(time_allowance=20)
    canceled = False
    while not navigator.isTaskComplete(task=teleop_task):
        feedback = navigator.getFeedback(task=teleop_task)
        if not canceled and feedback and Duration.from_msg(feedback.current_teleop_duration) > Duration(seconds=1.0):
            navigator.cancelTask()
            canceled = True
    teleop = report(navigator, "Assisted teleop")
    results.append(TaskResult.SUCCEEDED if teleop == TaskResult.CANCELED else teleop)

    go_to_pose_task = navigator.goToPose(make_pose(navigator, 0.0, 0.0, 0.0))
    while not navigator.isTaskComplete(task=go_to_pose_task):
        pass
    results.append(report(navigator, "Return to start"))

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0 if all(r == TaskResult.SUCCEEDED for r in results) else 1)


if __name__ == "__main__":
    main()
