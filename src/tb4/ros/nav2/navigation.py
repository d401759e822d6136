"""bt_navigator and waypoint_follower: navigate_to_pose, navigate_through_poses, follow_waypoints, the `goal_pose`
topic (RViz's Nav2 Goal tool) and the latched `goals` topic that announces every goal's poses."""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING

from geometry_msgs.msg import PoseStamped
from nav2_msgs import action as nav2_action
from nav_msgs.msg import Goals

from tb4.core.waits import wait_until
from tb4.ros.action_client import ActionClient
from tb4.ros.background import BackgroundNode
from tb4.ros.convert import checked_pose, pose_stamped, time_msg
from tb4.ros.nav2.goals import poses
from tb4.ros.qos import LATCHED
from tb4.wire import get_poses, result_code

if TYPE_CHECKING:
    from rclpy.node import Node

    from tb4.ros.nav2.interfaces import Nav2Interfaces

__all__ = ["NavigationServers", "Pose2D", "GoalPoseRelay"]

Pose2D = tuple[float, float, float]
GOAL_POSE_DISCOVERY = 10.0  # s the first goal_pose waits for its client to discover navigate_to_pose


class NavigationServers:
    """The navigation actions of bt_navigator and waypoint_follower, served by the core's navigators."""

    def __init__(self, nav2: Nav2Interfaces) -> None:
        self.loop = nav2.loop
        nav = nav2.loop.inputs.nav  # goals start tasks through the journaled inputs
        A = nav2_action
        node = nav2.nodes["bt_navigator"]
        # Latched: a recorder or viewer that joins late (or whose discovery lags) still gets the current goals.
        self.goals_pub = node.create_publisher(Goals, "goals", LATCHED)
        nav2.serve_action(
            "bt_navigator",
            A.NavigateToPose,
            "navigate_to_pose",
            lambda g: nav.start_navigate_to_pose(self.announce([checked_pose(g.pose, "goal pose")])[0]),
            invalid_code=result_code(A.NavigateToPose, "UNKNOWN"),
        )
        nav2.serve_action(
            "bt_navigator",
            A.NavigateThroughPoses,
            "navigate_through_poses",
            lambda g: nav.start_navigate_through_poses(self.announce(poses(get_poses(g, "poses")))),
            invalid_code=result_code(A.NavigateThroughPoses, "UNKNOWN"),
        )
        nav2.serve_action(
            "waypoint_follower",
            A.FollowWaypoints,
            "follow_waypoints",
            lambda g: nav.start_follow_waypoints(
                self.announce(poses(g.poses)), int(g.number_of_loops), int(g.goal_index)
            ),
            invalid_code=result_code(A.FollowWaypoints, "NO_VALID_WAYPOINTS"),
        )
        self.goal_pose = GoalPoseRelay(node)
        node.create_subscription(PoseStamped, "goal_pose", self.goal_pose.on_goal_pose, 10)

    def announce(self, goal_poses: list[Pose2D]) -> list[Pose2D]:
        """Publish the goal poses on `goals` (recordings and viewers show them), then hand them on."""
        now = self.loop.sim.time
        msg = Goals()
        msg.header.frame_id = "map"
        msg.header.stamp = time_msg(now)
        msg.goals = [pose_stamped(p, now) for p in goal_poses]
        self.goals_pub.publish(msg)
        return goal_poses

    def close(self) -> None:
        self.goal_pose.close()


class GoalPoseRelay:
    """Like Nav2's bt_navigator: a PoseStamped on goal_pose (RViz's Nav2 Goal tool) becomes a navigate_to_pose
    goal, sent through the action so that feedback and results flow as usual.

    Its action client lives in a node of its own, made at the first goal_pose. An idle client in the simulator's
    nodes still took every feedback and status message of every goal, and each one woke the simulator's executor,
    which rebuilds its whole wait set in Python: 1,683 of the 1,780 wake-ups of a three-robot delivery run, about
    9 ms of CPU each."""

    def __init__(self, node: Node) -> None:
        self._namespace = node.get_namespace()
        self._logger = node.get_logger()
        self._lock = threading.Lock()
        self._relay: BackgroundNode | None = None
        self._client: ActionClient | None = None
        self._closed = False

    def on_goal_pose(self, msg: PoseStamped) -> None:
        try:
            checked_pose(msg, "goal_pose")
        except ValueError as exc:
            self._logger.warn(f"goal_pose ignored: {exc}")
            return
        with self._lock:
            client = self._ready_client()
            if client is not None:
                client.send_goal_async(nav2_action.NavigateToPose.Goal(pose=msg))

    def _ready_client(self) -> ActionClient | None:
        if self._closed:
            return None
        if self._client is None:
            self._relay = BackgroundNode("bt_navigator_goal_pose", self._namespace, signal_handlers=False)
            with self._relay.paused():
                self._client = ActionClient(self._relay.node, nav2_action.NavigateToPose, "navigate_to_pose")
            self._relay.start()
        client = self._client
        # polled, not client.wait_for_server(): close() (the simulator stopping) ends the wait at once
        found = wait_until(lambda: self._closed or client.server_is_ready(), GOAL_POSE_DISCOVERY)
        if self._closed:
            return None
        if not found:
            self._logger.warn(f"goal_pose dropped: navigate_to_pose not found within {GOAL_POSE_DISCOVERY:g} s")
            return None
        return client

    def close(self) -> None:
        self._closed = True  # before the lock: a first goal_pose waiting for discovery gives up
        with self._lock:
            if self._relay is not None:
                self._relay.close()
                self._relay = self._client = None
