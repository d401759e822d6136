"""The goal_pose relay: with no navigate_to_pose server to be found, closing it (the simulator stopping) ends a
first goal_pose's discovery wait at once, and the goal is dropped, not sent later."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest
import rclpy
from geometry_msgs.msg import PoseStamped

from tb4.ros.nav2.navigation import GOAL_POSE_DISCOVERY, GoalPoseRelay


@pytest.fixture
def node() -> Iterator[rclpy.node.Node]:
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("goal_pose_relay_probe", namespace="/nobody_serves_here", context=context)
    yield node
    node.destroy_node()
    rclpy.try_shutdown(context=context)


def test_close_ends_the_first_goal_poses_discovery_wait(node: rclpy.node.Node) -> None:
    relay = GoalPoseRelay(node)
    goal = PoseStamped()
    goal.header.frame_id = "map"
    goal.pose.orientation.w = 1.0
    sender = threading.Thread(target=relay.on_goal_pose, args=(goal,), daemon=True)
    sender.start()
    time.sleep(0.5)  # the relay's node is made and it is waiting for the server
    started = time.monotonic()
    relay.close()
    sender.join(timeout=GOAL_POSE_DISCOVERY + 5.0)
    assert not sender.is_alive()
    assert time.monotonic() - started < GOAL_POSE_DISCOVERY / 2  # not the whole discovery limit
