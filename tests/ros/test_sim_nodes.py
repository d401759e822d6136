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
