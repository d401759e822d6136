"""The Nav2 side of the simulator: the nodes a TurtleBot 4 running Nav2 offers, each with its upstream name.

Each Nav2 server is a real node (bt_navigator, planner_server, ...) answering `<node>/get_state`, so scripts (ours
or upstream's) find the same graph they find on a robot. The work is done by tb4.nav.NavigationCore in the
simulator loop; the modules of this package only convert messages, one module per server.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.context import Context
from rclpy.node import Node

from tb4.nav.server import NavigationCore
from tb4.ros.action_bridge import TaskActionServer
from tb4.ros.amcl_node import AmclInterfaces
from tb4.ros.docking_server import DockingServer
from tb4.ros.loop import LoopView
from tb4.ros.nav2.costmaps import CostmapServers
from tb4.ros.nav2.lifecycle import LOCALIZATION_NODES, MANAGERS, NAVIGATION_NODES, Lifecycle
from tb4.ros.nav2.map_server import MapChangeHandler, MapServer
from tb4.ros.nav2.motion_servers import BehaviorServer, ControllerServer
from tb4.ros.nav2.navigation import NavigationServers
from tb4.ros.nav2.planner_server import PlannerServer, SmootherServer
from tb4.ros.run_record import RobotRecord
from tb4.ros.side_tasks import SideTasks
from tb4.ros.sim_node import SimNode

__all__ = ["Nav2Interfaces"]


class Nav2Interfaces:
    """Creates the Nav2 nodes in `namespace` and has each server wire its node to the loop's NavigationCore."""

    def __init__(
        self,
        context: Context,
        loop: LoopView,
        namespace: str = "",
        on_map_change: MapChangeHandler | None = None,
        record: RobotRecord | None = None,
    ):
        self.record = record
        self.loop = loop
        self.nav: NavigationCore = loop.nav
        self.namespace = namespace
        self.callback_group = ReentrantCallbackGroup()
        self.lifecycle = Lifecycle(loop, self.callback_group)
        self.nodes: dict[str, Node] = {}
        self._context = context
        for name in NAVIGATION_NODES + LOCALIZATION_NODES:
            self.lifecycle.serve_state(name, self._node(name))
        for manager, managed in MANAGERS.items():
            self.lifecycle.serve_manager(self._node(manager), managed)
        self._node("global_costmap", "global_costmap")
        self._node("local_costmap", "local_costmap")

        self.side = SideTasks(loop)  # tasks stepped beside the motion task: route tracking
        self.navigation = NavigationServers(self)
        self.planner = PlannerServer(self)
        self.smoother = SmootherServer(self)
        self.controller = ControllerServer(self)
        self.behaviors = BehaviorServer(self)
        self.docking = DockingServer(self)
        self.costmaps = CostmapServers(self)
        self.map_server = MapServer(self, on_map_change)
        self.amcl = AmclInterfaces(self.nodes["amcl"], loop, self.lifecycle.states, self.callback_group)

    @property
    def states(self) -> dict[str, str]:
        """Lifecycle state label of each managed node."""
        return self.lifecycle.states

    def all_nodes(self) -> list[Node]:
        return list(self.nodes.values())

    def close(self) -> None:
        """End what runs beside the nodes (the goal_pose relay's own node)."""
        self.navigation.close()

    def serve_action(
        self, owner: str, action_type: Any, name: str, start: Callable[[Any], Any], **kwargs: Any
    ) -> TaskActionServer:
        """An action on node `owner` whose goals become core tasks; goals are rejected while `owner` is not active."""
        return TaskActionServer(
            self.nodes[owner],
            self.loop,
            action_type,
            name,
            start,
            stamp=lambda: self.loop.sim.time,
            accept=self.lifecycle.goal_filter(owner, self.nodes[owner]),
            record=self.record,
            **kwargs,
        )

    def _node(self, name: str, sub_namespace: str = "") -> Node:
        ns = self.namespace.rstrip("/")
        full_ns = f"{ns}/{sub_namespace}" if sub_namespace else (ns or "/")
        node = SimNode(
            name, namespace=full_ns, context=self._context, parameter_overrides=[], use_global_arguments=False
        )
        self.nodes[f"{sub_namespace}/{name}" if sub_namespace else name] = node
        return node
