"""The simulator's nodes are SimNodes: no QoS event handler waitables for its executor to rebuild at every
wake-up (they were 120 of one robot's 146 waitables, 362 of a three-robot fleet's 440)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
import rclpy
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
    finally:
        simulator.close()
