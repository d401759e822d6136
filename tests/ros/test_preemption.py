"""Preemption said out loud, over real DDS: two clients in two nodes send navigate_to_pose goals to one robot. The
goal a newer one replaces ends ABORTED (as in Nav2) with the action's UNKNOWN code and a message naming the newer
goal, and the simulator logs which goal preempted which; likewise for a goal replaced by its own client's next one.
"""

from __future__ import annotations

from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.action import Undock
from nav2_msgs.action import NavigateToPose
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tb4.core.waits import wait_for_future
from tb4.ros.action_bridge import short_goal_id
from tb4.wire import result_code

from .rosclient import RosClient, navigate_to_pose_goal

SUCCEEDED, CANCELED, ABORTED = 4, 5, 6
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def test_a_goal_preempted_by_another_clients_goal_says_so(start_simulator, ros) -> None:
    # 5x: each goal must still run when the next one comes (each is a minute of driving)
    sim = start_simulator("--rate", "5", "--world", "warehouse")
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    initial = PoseWithCovarianceStamped()
    initial.header.frame_id = "map"
    initial.pose.pose.orientation.w = 1.0
    ros.publish_until(PoseWithCovarianceStamped, "initialpose", initial, amcl, what="amcl_pose")
    assert ros.action(Undock, "undock", Undock.Goal())[0] == SUCCEEDED

    other = RosClient("second_navigator")  # a second node, with its own action client
    try:
        other.action_client(NavigateToPose, "navigate_to_pose")
        first_feedback: list = []
        first = ros.send_goal(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(2.0, -23.0), first_feedback)
        assert first.accepted
        ros.settled(first_feedback, lambda f: len(f) >= 3, "the first goal's feedback")
        second = other.send_goal(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(9.6, 16.4))
        assert second.accepted
        ended = wait_for_future(first.get_result_async(), 30.0, "the preempted goal's result")
        first_id, second_id = short_goal_id(first.goal_id.uuid), short_goal_id(second.goal_id.uuid)
        unknown = result_code(NavigateToPose, "UNKNOWN")
        assert ended.status == ABORTED and ended.result.error_code == unknown
        assert ended.result.error_msg == (
            f"preempted by a newer navigate_to_pose goal (goal {second_id}) from this or another client"
        )
        line = f"navigate_to_pose goal {first_id} preempted by the newer navigate_to_pose goal {second_id}"
        assert sim.wait_for_output(line, timeout=10), sim.output()[-3000:]

        # the same client replaces its own goal: the same words, naming its newer goal
        third = other.send_goal(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(-12.8, -5.0))
        replaced = wait_for_future(second.get_result_async(), 30.0, "the replaced goal's result")
        third_id = short_goal_id(third.goal_id.uuid)
        assert (replaced.status, replaced.result.error_code) == (ABORTED, unknown)
        assert f"preempted by a newer navigate_to_pose goal (goal {third_id})" in replaced.result.error_msg
        assert sim.wait_for_output(f"goal {second_id} preempted by the newer navigate_to_pose goal {third_id}", 10)

        # a goal canceled by its client is not preempted: it ends CANCELED, and no preemption is logged
        wait_for_future(third.cancel_goal_async(), 10.0, "cancel response")
        canceled = wait_for_future(third.get_result_async(), 30.0, "the canceled goal's result")
        assert (canceled.status, canceled.result.error_msg) == (CANCELED, "")
        assert f"goal {third_id} preempted" not in sim.output()
    finally:
        other.close()
