"""A tiny server for the interface test: NavigateToPose (with feedback) and Create 3 Dock, in its own process.

Its replies wait (bounded) for the client's reply readers, as every server of ours does (tb4.ros.replies): a stock
rclpy server drops the reply to a client it has not discovered yet, which on a loaded machine lost a goal
response (stress run s13: no goal acceptance in 10 s)."""

from __future__ import annotations

import sys

import rclpy
from irobot_create_msgs.action import Dock
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionServer, GoalResponse
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node

from tb4.ros.replies import wait_for_action_reply_readers


class EchoServer(Node):
    def __init__(self) -> None:
        super().__init__("interface_echo_server")
        ActionServer(
            self, NavigateToPose, "navigate_to_pose", self._navigate, goal_callback=self._accept("navigate_to_pose")
        )
        ActionServer(self, Dock, "dock", self._dock, goal_callback=self._accept("dock"))

    def _accept(self, action: str):
        def accept(_goal) -> GoalResponse:
            wait_for_action_reply_readers(self, f"/{action}", "send_goal")
            return GoalResponse.ACCEPT

        return accept

    def _result_readable(self, action: str) -> None:
        wait_for_action_reply_readers(self, f"/{action}", "get_result")

    def _navigate(self, handle):
        feedback = NavigateToPose.Feedback()
        feedback.current_pose = handle.request.pose
        feedback.distance_remaining = 1.5
        handle.publish_feedback(feedback)
        handle.succeed()
        result = NavigateToPose.Result()
        result.error_code = NavigateToPose.Result.NONE
        result.error_msg = (
            f"reached {handle.request.pose.pose.position.x:.1f},{handle.request.pose.pose.position.y:.1f}"
        )
        self._result_readable("navigate_to_pose")
        return result

    def _dock(self, handle):
        handle.publish_feedback(Dock.Feedback(sees_dock=True))
        handle.succeed()
        self._result_readable("dock")
        return Dock.Result(is_docked=True)


def main() -> int:
    rclpy.init()
    node = EchoServer()
    print("echo server ready", flush=True)
    executor = MultiThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
