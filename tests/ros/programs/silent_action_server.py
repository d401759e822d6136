"""A NavigateToPose server that says nothing for a while: it accepts a goal, sends no feedback for SILENT seconds
(argv[1]), then succeeds; in the namespace argv[2]. In its own process, so that a test can stop it (SIGSTOP) or
kill it (SIGKILL) in the middle of a goal, or leave it alone to show that a quiet but healthy server is not taken
for gone."""

from __future__ import annotations

import contextlib
import os
import sys
import time

import rclpy
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionServer, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node

from tb4.ros.background import destroy_node_and_actions
from tb4.ros.replies import wait_for_action_reply_readers

READY = "silent server ready"
EXECUTING = "silent server executing"


class SilentServer(Node):
    def __init__(self, silent: float, namespace: str) -> None:
        super().__init__("silent_server", namespace=namespace)
        self.silent = silent
        ActionServer(
            self,
            NavigateToPose,
            "navigate_to_pose",
            self._navigate,
            goal_callback=self._accept,
            callback_group=ReentrantCallbackGroup(),  # the goal's wait must not hold the server's other requests
        )

    def _accept(self, _goal: NavigateToPose.Goal) -> GoalResponse:
        wait_for_action_reply_readers(self, self.resolve_service_name("navigate_to_pose"), "send_goal")
        return GoalResponse.ACCEPT

    def _navigate(self, handle):  # runs in one of the executor's threads: the others answer meanwhile
        print(EXECUTING, flush=True)
        time.sleep(self.silent)
        handle.succeed()
        wait_for_action_reply_readers(self, self.resolve_service_name("navigate_to_pose"), "get_result")
        return NavigateToPose.Result(error_code=NavigateToPose.Result.NONE)


def main() -> None:
    rclpy.init()
    node = SilentServer(float(sys.argv[1]), sys.argv[2])
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    print(READY, flush=True)
    with contextlib.suppress(KeyboardInterrupt, ExternalShutdownException):
        executor.spin()
    # out at once, without waiting for the executor thread that may sleep in a goal
    destroy_node_and_actions(node)
    rclpy.try_shutdown()
    sys.stdout.flush()
    os._exit(0)


if __name__ == "__main__":
    main()
