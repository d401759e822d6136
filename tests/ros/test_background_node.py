"""Closing a BackgroundNode frees its DDS participant at once, action clients and servers included.

rclpy's destroy_node leaves action clients and servers to the garbage collector, and they keep the participant
(its ports, and the node in everyone's graph) alive until it runs. With LOCALHOST discovery, participants numbered
past the first 32 of a domain on a machine never discover one another, so a test session that piled them up lost
discovery between a fresh client and a fresh server (4 of 150 make-and-drop cycles in one process).
"""

from __future__ import annotations

import gc

from nav2_msgs.action import ComputePathToPose
from rclpy.action import ActionServer

from tb4.core.waits import wait_until
from tb4.ros.action_client import ActionClient
from tb4.ros.background import BackgroundNode


def test_a_closed_node_with_action_endpoints_leaves_the_graph_without_the_garbage_collector() -> None:
    observer = BackgroundNode("participant_observer")
    observer.start()
    gc.disable()  # what frees the participant must be close(), not a collection that happens to run
    try:
        probe = BackgroundNode("closing_probe")
        ActionClient(probe.node, ComputePathToPose, "closing_probe_client")
        ActionServer(probe.node, ComputePathToPose, "closing_probe_server", execute_callback=lambda handle: None)
        probe.start()

        def probe_listed() -> bool:
            return "closing_probe" in [name for name, _ in observer.node.get_node_names_and_namespaces()]

        assert wait_until(probe_listed, 20.0), "the observer never discovered the probe"
        probe.close()
        del probe
        assert wait_until(lambda: not probe_listed(), 10.0), "the closed node is still in the graph after 10 s"
    finally:
        gc.enable()
        observer.close()
