"""Every topic the simulator publishes reaches rclpy's default subscription (reliable, volatile, depth 10) and a
sensor-data one (best effort). The topics are discovered at run time from the graph, so a topic added later is
covered without editing this test; events that publish only on change (a button press, an initial pose, a goal)
are triggered the way a user would.

Latched topics (map, tf_static, the global costmap: transient local, as map_server and tf2 publish them) send
their message once: a volatile subscriber that joins later matches them but only gets later messages, on the
robot as here. For those, both profiles must match the publisher, and a transient-local subscriber gets the
message."""

from __future__ import annotations

import importlib
import time

from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import ComputeRoute, NavigateToPose
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data

from tb4.core.waits import wait_for_future, wait_until
from tb4.nav.route_graph import load_route_graph
from tb4.processes import tb4_command
from tb4.sim.world import load_world

INFRASTRUCTURE = {"/rosout", "/parameter_events"}  # every node's, not the simulator's interface
EXPECTED = {
    "/odom", "/tf", "/tf_static", "/scan", "/clock", "/battery_state", "/dock_status", "/hazard_detection",
    "/ir_intensity", "/cliff_intensity", "/imu", "/mouse", "/wheel_vels", "/wheel_ticks", "/wheel_status",
    "/slip_status", "/stop_status", "/kidnap_status", "/interface_buttons", "/ir_opcode", "/map", "/plan",
    "/goals", "/amcl_pose",
}  # fmt: skip


def _message_class(type_name: str):
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def _latched(ros, topic: str) -> bool:
    infos = ros.node.get_publishers_info_by_topic(topic)
    return any(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)


def _published_topics(ros, settle: float = 3.0, timeout: float = 30.0) -> dict[str, str]:
    """Topics with a publisher outside this test, once the list has been stable for `settle` seconds."""
    me = ros.node.get_name()
    deadline, stable_since, last = time.monotonic() + timeout, time.monotonic(), {}
    while time.monotonic() < deadline:
        found = {}
        for name, types in ros.node.get_topic_names_and_types():
            if name in INFRASTRUCTURE or "/_action/" in name:
                continue
            if any(info.node_name != me for info in ros.node.get_publishers_info_by_topic(name)):
                found[name] = types[0]
        if found != last:
            last, stable_since = found, time.monotonic()
        elif found and time.monotonic() - stable_since >= settle:
            return found
        time.sleep(0.2)
    return last


def test_every_published_topic_reaches_default_and_sensor_data_subscribers(start_simulator, start_process, ros):
    start_simulator("--rate", "5", "--world", "depot")
    topics = _published_topics(ros)
    assert set(topics) >= EXPECTED, sorted(EXPECTED - set(topics))
    got: dict[tuple[str, str], int] = {}

    def counter(key: tuple[str, str]):
        def on(_msg) -> None:
            got[key] = got.get(key, 0) + 1

        return on

    latched = {name for name in topics if _latched(ros, name)}
    assert {"/map", "/tf_static"} <= latched
    subscriptions = {}
    for name, type_name in topics.items():
        cls = _message_class(type_name)
        subscriptions[(name, "default")] = ros.node.create_subscription(cls, name, counter((name, "default")), 10)
        subscriptions[(name, "sensor_data")] = ros.node.create_subscription(
            cls, name, counter((name, "sensor_data")), qos_profile_sensor_data
        )
        if name in latched:
            ros.node.create_subscription(cls, name, counter((name, "latched")), LATCHED)

    # The goals' clients now, so that the simulator matches them while the subscriptions match (s45, beside two busy
    # processes: a client created just before its goal had no answer in 10 s).
    ros.action_client(NavigateToPose, "navigate_to_pose")
    ros.action_client(ComputeRoute, "compute_route")

    # The events below publish once or on change. Each subscription first matches the simulator's publisher
    # (discovery takes seconds on a loaded machine): a one-off message sent before that reaches nobody.
    def unmatched() -> list[tuple[str, str]]:
        return sorted(key for key, sub in subscriptions.items() if sub.get_publisher_count() == 0)

    wait_until(lambda: not unmatched(), 30.0)
    assert not unmatched(), f"not matched with the simulator's publisher within 30 s (QoS incompatible?): {unmatched()}"

    # Events: a button press, an initial pose (amcl_pose), a goal (goals, plan), a route (route).
    for args in (("press", "1"), ("pose", "0", "0", "0")):
        proc = start_process(tb4_command(*args), name=args[0])
        assert proc.popen.wait(30) == 0, proc.output()
    goal = NavigateToPose.Goal(pose=PoseStamped())
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y = -2.0, -1.0
    goal.pose.pose.orientation.w = 1.0
    handle = ros.send_goal(NavigateToPose, "navigate_to_pose", goal)
    # A route between two graph nodes (route).
    graph = load_route_graph(load_world("depot").route_graph)
    edge = graph.edges[min(graph.edges)]
    route = ComputeRoute.Goal(start_id=edge.start, goal_id=edge.end)
    ros.send_goal(ComputeRoute, "compute_route", route)

    wanted = {(name, p) for name in set(topics) - latched for p in ("default", "sensor_data")}
    wanted |= {(name, "latched") for name in latched}
    deadline = time.monotonic() + 30.0
    asked = time.monotonic()
    while time.monotonic() < deadline and not wanted <= set(got):
        # a route goes out once per request: best effort may lose that one message (a stress run saw it), so a
        # sensor-data subscriber still waiting asks for another route, as a user would
        if ("/route", "sensor_data") in wanted - set(got) and time.monotonic() - asked > 5.0:
            ros.send_goal(ComputeRoute, "compute_route", route)
            asked = time.monotonic()
        time.sleep(0.1)
    if handle.accepted:
        wait_for_future(handle.cancel_goal_async(), 10.0, "cancel")
    missing = sorted(wanted - set(got))
    assert not missing, f"no message within 30 s on: {missing}"
