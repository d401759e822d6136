"""The lifecycle side of Nav2's nodes: each answers `<node>/get_state`, and the two lifecycle managers start,
pause, reset and shut down their nodes. Pausing the navigation nodes pauses the core (no new tasks)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from nav2_msgs.srv import ManageLifecycleNodes
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from std_srvs.srv import Trigger

from tb4.ros.loop import LoopView
from tb4.ros.replies import create_service

__all__ = ["Lifecycle", "NAVIGATION_NODES", "LOCALIZATION_NODES", "MANAGERS"]

NAVIGATION_NODES = (
    "controller_server",
    "smoother_server",
    "planner_server",
    "behavior_server",
    "bt_navigator",
    "waypoint_follower",
    "docking_server",
    "route_server",
)
LOCALIZATION_NODES = ("map_server", "amcl")
#: Each lifecycle manager and the nodes it manages (upstream's two launch files).
MANAGERS = {
    "lifecycle_manager_navigation": NAVIGATION_NODES,
    "lifecycle_manager_localization": LOCALIZATION_NODES,
}
_STATE_IDS = {
    "unconfigured": State.PRIMARY_STATE_UNCONFIGURED,
    "inactive": State.PRIMARY_STATE_INACTIVE,
    "active": State.PRIMARY_STATE_ACTIVE,
    "finalized": State.PRIMARY_STATE_FINALIZED,
}
_TRANSITIONS = {
    ManageLifecycleNodes.Request.STARTUP: "active",
    ManageLifecycleNodes.Request.RESUME: "active",
    ManageLifecycleNodes.Request.PAUSE: "inactive",
    ManageLifecycleNodes.Request.CONFIGURE: "inactive",
    ManageLifecycleNodes.Request.RESET: "unconfigured",
    ManageLifecycleNodes.Request.CLEANUP: "unconfigured",
    ManageLifecycleNodes.Request.SHUTDOWN: "finalized",
}


class Lifecycle:
    """The state label of every managed node (all start active, as after upstream's bringup)."""

    def __init__(self, loop: LoopView, group: CallbackGroup) -> None:
        self.loop = loop
        self._group = group
        self.states: dict[str, str] = {name: "active" for name in (*NAVIGATION_NODES, *LOCALIZATION_NODES)}

    def is_active(self, name: str) -> bool:
        return self.states.get(name) == "active"

    def serve_state(self, name: str, node: Node) -> None:
        """`<node>/get_state`, as every lifecycle node offers it."""

        def handler(_request: Any, response: Any) -> Any:
            label = self.states[name]
            response.current_state = State(id=_STATE_IDS[label], label=label)
            return response

        create_service(node, GetState, "~/get_state", handler, callback_group=self._group)

    def serve_manager(self, node: Node, managed: tuple[str, ...]) -> None:
        """`<manager>/manage_nodes` and `<manager>/is_active` for the nodes in `managed`."""
        create_service(node, ManageLifecycleNodes, "~/manage_nodes", self._manage(managed), callback_group=self._group)
        create_service(node, Trigger, "~/is_active", self._is_active(managed), callback_group=self._group)

    def goal_filter(self, name: str, node: Node) -> Callable[[Any], bool]:
        """An action server's accept callback: goals only while `name` is active (as a real lifecycle node)."""

        def accept(_goal: Any) -> bool:
            if self.is_active(name):
                return True
            node.get_logger().warn(f"goal rejected: {name} is {self.states.get(name)}, not active")
            return False

        return accept

    def _is_active(self, managed: tuple[str, ...]) -> Callable:
        def handler(_request: Any, response: Any) -> Any:
            response.success = all(self.is_active(n) for n in managed)
            response.message = ", ".join(f"{n}: {self.states[n]}" for n in managed)
            return response

        return handler

    def _manage(self, managed: tuple[str, ...]) -> Callable:
        def handler(request: Any, response: Any) -> Any:
            target = _TRANSITIONS.get(request.command)
            if target is None:
                response.success = False
                return response
            for name in managed:
                # A finalized node stays finalized, except through STARTUP (what a relaunch would do).
                stuck = self.states[name] == "finalized" and target != "finalized"
                if stuck and request.command != ManageLifecycleNodes.Request.STARTUP:
                    continue
                self.states[name] = target
            if "bt_navigator" in managed:
                nav = self.loop.inputs.nav
                nav.resume() if target == "active" else nav.pause()
            response.success = True
            return response

        return handler
