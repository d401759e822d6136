"""The viewer's ROS side: one rclpy context and one spin thread, with a RobotBridge per viewed namespace.

All rclpy calls run in the spin thread (a tb4.ros.background.BackgroundSpinner whose turn also runs the work the
web server hands over with `submit`). Each turn drains what the subscriptions hold (depth 1: only the newest)
and then sleeps out DRAIN_PERIOD, so however fast the simulator runs the viewer handles a bounded number of
messages per second and never queues old ones.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any, TypeVar

import rclpy

from tb4.ros.background import BackgroundSpinner
from tb4.ros.handoff import Handoff
from tb4.viewer.protocol import CancelCommand, Command, PoseCommand, PressCommand
from tb4.viewer.robot_bridge import RobotBridge
from tb4.viewer.state import ViewerState
from tb4.viewer.world_info import WorldInfoCache

__all__ = ["ViewerBridge", "DRAIN_PERIOD", "NAMESPACE_SCAN_PERIOD"]

T = TypeVar("T")

DRAIN_PERIOD = 0.04  # s between two drains of the subscriptions: at most 25 messages per topic and second
NAMESPACE_SCAN_PERIOD = 2.0  # s between two looks at the graph for robot namespaces
ERROR_REPORT_PERIOD = 5.0  # s: at most one "callback failed" line per period on stderr


class _ViewerSpinner(BackgroundSpinner):
    """The spin thread's turn: run submitted work, drain the subscriptions, now and then look for namespaces."""

    def __init__(self, bridge: ViewerBridge) -> None:
        super().__init__(name="tb4-viewer-ros", context=bridge.context, on_error=self._report)
        self.bridge = bridge
        self._next_scan = 0.0
        self._last_error = -math.inf

    def turn(self) -> None:
        start = time.monotonic()
        try:
            self.bridge._ops.run_pending()
            self._drain()
            if start >= self._next_scan:
                self._next_scan = start + NAMESPACE_SCAN_PERIOD
                self.bridge._scan_namespaces()
        finally:
            time.sleep(max(0.0, DRAIN_PERIOD - (time.monotonic() - start)))

    def _drain(self) -> None:
        """Take what is ready now (each subscription holds at most its newest message), then return."""
        robots = self.bridge._robots
        for _ in range(64):
            before = sum(r.callbacks for r in robots.values())
            self.executor.spin_once(timeout_sec=0.0)
            if sum(r.callbacks for r in robots.values()) == before:
                return

    def _report(self, exc: Exception) -> None:
        """One bad callback must not end the viewer's ROS side: say so on stderr, at a bounded rate."""
        now = time.monotonic()
        if now - self._last_error > ERROR_REPORT_PERIOD:
            self._last_error = now
            print(f"tb4 view: ROS callback failed: {type(exc).__name__}: {exc}", file=sys.stderr)

    def finish(self) -> None:
        self.bridge._shutdown()


class ViewerBridge:
    """One rclpy context and spin thread for the viewer; RobotBridges are created per namespace on demand."""

    def __init__(
        self, default_namespace: str = "", world: dict[str, Any] | None = None, robot_radius: float | None = None
    ):
        self.default_namespace = default_namespace
        self.world = world
        self.robot_radius = robot_radius
        self.worlds = WorldInfoCache()
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self._ops = Handoff(lambda: RuntimeError("the viewer's ROS bridge is stopped"))
        self._robots: dict[str, RobotBridge] = {}
        self._users: dict[str, int] = {}
        self._namespaces: list[str] = [default_namespace]
        self._robot_namespaces: list[str] = []  # namespaces with a robot's odom topic, from the last graph scan
        self._spinner = _ViewerSpinner(self)
        self.executor = self._spinner.executor
        self._spinner.start()
        try:
            self.acquire(default_namespace, timeout=20.0)  # the default namespace stays subscribed (warm state)
        except BaseException:
            self.close()
            raise

    # --- called from any thread ---------------------------------------------------------------------------
    def submit(self, fn: Callable[[], T]) -> Future:
        """Run `fn` in the spin thread (where every rclpy call happens); the future carries its result."""
        return self._ops.submit(fn)

    def acquire(self, namespace: str, timeout: float = 10.0, detailed: bool = True) -> ViewerState:
        """Start (or share) the bridge of a namespace; pair with release(). `detailed`: everything the page shows
        and its tools (the commanded robot); otherwise the overview a fleet robot is drawn from."""

        def op() -> ViewerState:
            robot = self._robots.get(namespace)
            if robot is None:
                state = ViewerState(namespace, robot_radius=self.robot_radius)
                world = self.world if namespace == self.default_namespace else None
                robot = RobotBridge(self.context, namespace, state, self.worlds, world, detailed)
                self._robots[namespace] = robot
                self.executor.add_node(robot.node)
            elif detailed:
                robot.add_details()
            self._users[namespace] = self._users.get(namespace, 0) + 1
            return robot.state

        return self.submit(op).result(timeout=timeout)

    def release(self, namespace: str) -> None:
        """A page stopped viewing `namespace`: drop its node when nobody else does (never the default one)."""

        def op() -> None:
            users = self._users.get(namespace, 0) - 1
            self._users[namespace] = max(0, users)
            if users <= 0 and namespace != self.default_namespace and namespace in self._robots:
                robot = self._robots.pop(namespace)
                self.executor.remove_node(robot.node)
                robot.destroy()

        self.submit(op)

    def robot(self, namespace: str) -> RobotBridge:
        """The bridge of a namespace (only from the spin thread, i.e. inside a submitted function)."""
        robot = self._robots.get(namespace)
        if robot is None:
            raise RuntimeError(f"namespace '{namespace or '/'}' is not being viewed")
        return robot

    def namespaces(self) -> list[str]:
        return list(self._namespaces)

    def initial_namespace(self) -> str:
        """The robot a new page commands: the one asked for; without one (`tb4 view` against `tb4 sim --robots
        3`), the un-namespaced robot if there is one, else the first namespace with a robot (/robot1)."""
        found = self._robot_namespaces
        if self.default_namespace or "" in found or not found:
            return self.default_namespace
        return found[0]

    def command(self, namespace: str, command: Command, timeout: float = 10.0) -> str:
        """Carry out a page's tool command in `namespace`; returns what was done, raises RuntimeError if it can't."""

        def op() -> str:
            robot = self.robot(namespace)
            if isinstance(command, PoseCommand) and command.kind == "initial_pose":
                return robot.publish_initial_pose(command.x, command.y, command.yaw)
            if isinstance(command, PoseCommand) and command.kind == "goal":
                return robot.send_goal(command.x, command.y, command.yaw)
            if isinstance(command, CancelCommand):
                return robot.cancel_all()
            if isinstance(command, PressCommand):
                return robot.create3.press(command.button)
            raise ValueError(f"not a ROS command: {command!r}")

        return self.submit(op).result(timeout=timeout)

    def close(self, timeout: float = 5.0) -> None:
        self._spinner.stop(timeout=timeout)

    @property
    def alive(self) -> bool:
        """Whether the spin thread still runs (the page's data is live)."""
        return self._spinner.alive

    # --- the spin thread ------------------------------------------------------------------------------------
    def _scan_namespaces(self) -> None:
        """Robot namespaces are those with a published Odometry `odom` topic; the root one is listed only if it has
        a robot or no other robot is found (a fleet has none there), or when it was asked for."""
        robot = self._robots.get(self.default_namespace)
        if robot is None:
            return
        robots = set()
        for name, types in robot.node.get_topic_names_and_types():
            if name.endswith("/odom") and "nav_msgs/msg/Odometry" in types and robot.node.count_publishers(name):
                robots.add(name[: -len("/odom")])  # published: a robot (the viewer's own subscriptions are listed too)
        found = robots | {ns for ns in self._robots if ns}
        if self.default_namespace or "" in robots or not robots:
            found.add(self.default_namespace)
        self._robot_namespaces = sorted(robots)
        self._namespaces = sorted(found)

    def _shutdown(self) -> None:
        for robot in list(self._robots.values()):
            self.executor.remove_node(robot.node)
            robot.destroy()
        self._robots.clear()
        self.executor.shutdown(timeout_sec=1.0)
        rclpy.try_shutdown(context=self.context)
        self._ops.close(RuntimeError("the viewer's ROS bridge stopped"))
