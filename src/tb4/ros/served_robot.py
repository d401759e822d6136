"""One robot's whole ROS surface in the simulator process: the Create 3, Nav2's servers, the route server, GPS,
ground truth and the world topic, all under the robot's namespace. A fleet serves one of these per robot on the
same loop; tf goes out on the namespace's own `tf`/`tf_static` (as the TurtleBot 4 multi-robot setup remaps them),
with the frames unprefixed."""

from __future__ import annotations

from typing import Any

from rclpy.node import Node

from tb4.nav.route_graph import RouteGraph
from tb4.ros.create3_interfaces import Create3Interfaces
from tb4.ros.gps import GpsInterfaces
from tb4.ros.ground_truth import GroundTruthPublisher
from tb4.ros.loop import LoopView
from tb4.ros.nav2 import Nav2Interfaces
from tb4.ros.routes import RouteServer
from tb4.ros.run_record import RobotRecord
from tb4.ros.sim_node import SimNode
from tb4.ros.world_topic import WorldAnnouncer
from tb4.sim.world import World

__all__ = ["ServedRobot"]


class ServedRobot:
    """Builds and owns one robot's nodes; `clock`: whether this robot publishes the process's one /clock;
    `fleet`: every namespace of the fleet this robot is part of (announced on `fleet`; empty for one robot)."""

    def __init__(
        self,
        context: Any,
        loop: LoopView,
        world: World,
        route_graph: RouteGraph | None,
        namespace: str,
        record: RobotRecord | None = None,
        clock: bool = True,
        fleet: tuple[str, ...] = (),
    ) -> None:
        self.namespace = namespace
        self.sim = loop.sim
        self.nav = loop.nav
        self.node = SimNode("turtlebot4_sim", namespace=namespace or "/", context=context)
        self.create3 = Create3Interfaces(self.node, loop, record=record, clock=clock)
        self.world_topic = WorldAnnouncer(self.node, world, fleet)
        self.nav2 = Nav2Interfaces(
            context,
            loop,
            namespace,
            on_map_change=lambda _grid, _path: self.world_topic.withdraw(),
            record=record,
        )
        self.routes = RouteServer(self.nav2, route_graph, self.nav2.side)
        self.gps = GpsInterfaces(self.nav2, self.node, world.datum)
        self.ground_truth = GroundTruthPublisher(self.node, loop)
        self.nav2.amcl.on_pose.append(self.ground_truth.beside_estimate)  # each estimate pairs with its truth

    def nodes(self) -> list[Node]:
        """Every node of this robot, for the executor."""
        return [self.node, *self.create3.nodes(), *self.nav2.all_nodes()]

    def close(self) -> None:
        """End what runs beside the executor's nodes (before they are destroyed)."""
        self.nav2.close()
