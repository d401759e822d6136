"""The simulator's nodes are SimNodes: no QoS event handler waitables for its executor to rebuild at every
wake-up (they were 120 of one robot's 146 waitables, 362 of a three-robot fleet's 440), and each subscription takes
its messages in order in a callback group of its own."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.event_handler import EventHandler

from tb4.ros.sim_node import SimNode
from tb4.ros.simulator import Simulator, SimulatorOptions


@pytest.fixture
def context() -> Iterator[rclpy.Context]:
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


@pytest.mark.parametrize("robots", [0, 2])
def test_every_node_of_the_simulator_is_a_sim_node_without_event_handlers(context: rclpy.Context, robots: int) -> None:
    simulator = Simulator(SimulatorOptions(world="warehouse", robots=robots, hold=True), context=context)
    try:
        nodes = simulator.all_nodes()
        assert len(nodes) >= 16 * max(robots, 1)
        assert all(isinstance(node, SimNode) for node in nodes), [
            n.get_name() for n in nodes if not isinstance(n, SimNode)
        ]
        handlers = [(n.get_name(), w) for n in nodes for w in n.waitables if isinstance(w, EventHandler)]
        assert handlers == []
        assert sum(len(list(n.publishers)) for n in nodes) >= 50 * max(robots, 1)  # the topics are all there
        subscriptions = [(n.get_name(), s) for n in nodes for s in n.subscriptions]
        assert len(subscriptions) >= 10 * max(robots, 1)
        shared = [
            (name, s.topic_name)
            for name, s in subscriptions
            if not isinstance(s.callback_group, MutuallyExclusiveCallbackGroup)
            or sum(other.callback_group is s.callback_group for _, other in subscriptions) > 1
        ]
        assert shared == [], "subscriptions whose messages can overtake each other"
    finally:
        simulator.close()


def test_an_idle_simulator_wakes_its_executor_only_for_work_and_ends_at_once(context: rclpy.Context) -> None:
    """Each executor turn rebuilds the wait set of every entity of every node: serving, the simulator turns it for
    work (and once a second at most when there is none), not every tenth of a second to look at its stop event;
    and a stop ends the serving at once, without waiting for a turn to time out."""
    import threading
    import time

    simulator = Simulator(SimulatorOptions(world="warehouse", hold=True), context=context)
    turns = []
    turn = simulator.executor.spin_once

    def counted(timeout_sec: float | None = None) -> None:
        turns.append(time.monotonic())
        turn(timeout_sec=timeout_sec)

    simulator.executor.spin_once = counted  # type: ignore[method-assign]
    stop = threading.Event()
    serving = threading.Thread(target=simulator.spin, args=(stop,), daemon=True)
    try:
        simulator.start()
        serving.start()
        time.sleep(3.0)
        idle = [t for t in turns if t > turns[0] + 0.5] if turns else []
        assert len(idle) <= 4, f"{len(idle)} executor turns in 2.5 s of an idle simulator"
        asked = time.monotonic()
        stop.set()
        serving.join(timeout=5.0)
        assert not serving.is_alive()
        assert time.monotonic() - asked < 0.5
    finally:
        stop.set()
        serving.join(timeout=5.0)
        simulator.close()


def test_two_initial_poses_sent_back_to_back_are_applied_in_the_order_sent(context: rclpy.Context) -> None:
    """The first message's thread held up (descheduled on a loaded machine) between taking its message and handing
    it to the world: the second must wait for it, as it does in Nav2's amcl, not overtake it. In a reentrant group
    it did, and amcl kept the first pose (seen in a `tb4 sim`: 0.20 applied before 0.10, 0.90 before 0.80)."""
    import threading
    import time

    from geometry_msgs.msg import PoseWithCovarianceStamped

    from tb4.core.waits import wait_until

    from .rosclient import RosClient

    simulator = Simulator(SimulatorOptions(world="warehouse", hold=True), context=context)
    amcl = simulator.nav2.amcl
    apply = amcl.set_initial_pose
    applied: list[float] = []
    taken: list[float] = []

    def held_up_first(msg: PoseWithCovarianceStamped, what: str) -> bool:
        taken.append(msg.pose.pose.position.x)
        if len(taken) == 1:
            time.sleep(0.5)
        ok = apply(msg, what)
        applied.append(msg.pose.pose.position.x)
        return ok

    amcl.set_initial_pose = held_up_first  # type: ignore[method-assign]
    stop = threading.Event()
    serving = threading.Thread(target=simulator.spin, args=(stop,), daemon=True)
    client = RosClient("order_client")
    try:
        simulator.start()
        serving.start()
        publisher = client.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        wait_until(lambda: publisher.get_subscription_count() >= 1, 20.0, "the simulator's initialpose reader")
        for x in (1.0, 0.0):
            msg = PoseWithCovarianceStamped()
            msg.header.frame_id = "map"
            msg.pose.pose.position.x = x
            msg.pose.pose.orientation.w = 1.0
            publisher.publish(msg)
        wait_until(lambda: len(applied) == 2, 10.0, "both initial poses applied")
        assert applied == [1.0, 0.0]
        pose = simulator.nav2.nav.pose()
        assert pose is not None and abs(pose[0]) < 1e-6  # the estimate is the last pose sent
    finally:
        client.close()
        stop.set()
        serving.join(timeout=5.0)
        simulator.close()


def test_a_sim_node_refuses_a_subscription_in_a_group_of_the_callers(context: rclpy.Context) -> None:
    """A shared group would let a topic's messages overtake each other again (reentrant), or hold them behind other
    callbacks (mutually exclusive): a simulator subscription gets a group of its own or none."""
    from rclpy.callback_groups import ReentrantCallbackGroup
    from std_msgs.msg import Empty

    node = SimNode("refusing_groups", context=context)
    try:
        with pytest.raises(ValueError, match="callback group of its own"):
            node.create_subscription(Empty, "anything", lambda _m: None, 10, callback_group=ReentrantCallbackGroup())
        assert list(node.subscriptions) == []
        own = node.create_subscription(Empty, "anything", lambda _m: None, 10)
        assert isinstance(own.callback_group, MutuallyExclusiveCallbackGroup)
    finally:
        node.destroy_node()
