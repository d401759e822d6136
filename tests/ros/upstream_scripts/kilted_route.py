#!/usr/bin/env python3
"""Kilted style (our own script), after Nav2's route example: compute and track a route with the route server and
hand each rerouted path to the controller with followPath, reading every route feedback in order.
Upstream import paths only."""

import rclpy
from geometry_msgs.msg import PoseStamped

from nav2_simple_commander.robot_navigator import BasicNavigator, RunningTask, TaskResult
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

    goal_pose = make_pose(navigator, -13.0, 9.0, 1.57)
    route = navigator.getRoute(initial_pose, goal_pose)
    if route is None:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Getting a route failed!:{error_code}:{error_msg}")
    else:
        print(f"Route with {len(route[1].nodes)} nodes and a path of {len(route[0].poses)} poses")

    route_tracking_task = navigator.getAndTrackRoute(initial_pose, goal_pose)
    last_feedback = None
    follow_path_task = RunningTask.NONE
    controller_done = False
    while not navigator.isTaskComplete(task=route_tracking_task):
        feedback = navigator.getFeedback(task=route_tracking_task)
        while feedback is not None:
            if not last_feedback or (
                feedback.last_node_id != last_feedback.last_node_id
                or feedback.next_node_id != last_feedback.next_node_id
            ):
                print(
                    f"Passed node {feedback.last_node_id} to next node {feedback.next_node_id}"
                    f" along edge {feedback.current_edge_id}."
                )
            last_feedback = feedback
            if feedback.rerouted:
                print("Passing new route to controller!")
                follow_path_task = navigator.followPath(feedback.path)
            feedback = navigator.getFeedback(task=route_tracking_task)
        if follow_path_task != RunningTask.NONE and navigator.isTaskComplete(task=follow_path_task):
            print("Controller or waypoint follower server completed its task!")
            controller_done = True
            navigator.cancelTask()

    result = navigator.getResult()
    if result == TaskResult.SUCCEEDED or (controller_done and result == TaskResult.CANCELED):
        print("Goal succeeded!")
    elif result == TaskResult.FAILED:
        (error_code, error_msg) = navigator.getTaskError()
        print(f"Goal failed!{error_code}:{error_msg}")
    else:
        print(f"Goal ended with {result.name}")

    navigator.destroyNode()
    rclpy.shutdown()
    exit(0)


if __name__ == "__main__":
    main()
