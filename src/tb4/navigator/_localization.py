"""Initial pose, waiting for Nav2 to be active, and lifecycle commands: all bounded, all with clear messages.

Upstream methods here: setInitialPose, waitUntilNav2Active, lifecycleStartup, lifecycleShutdown (and the helpers
_waitForNodeToActivate, _waitForInitialPose, _amclPoseCallback, _setInitialPose). GetState is polled as an
idempotent request; ManageLifecycleNodes STARTUP/SHUTDOWN are sent exactly once per manager.
"""

from __future__ import annotations

import math
import threading
import time

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from lifecycle_msgs.srv import GetState
from nav2_msgs.srv import ManageLifecycleNodes
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from tb4.core.waits import wait_until
from tb4.navigator._base import NavigatorBase
from tb4.navigator._validate import check_name, check_pose_stamped
from tb4.navigator.timeouts import NavigatorTimeout

__all__ = ["LocalizationMixin", "AMCL_POSE_QOS"]

AMCL_POSE_QOS = QoSProfile(
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
    reliability=ReliabilityPolicy.RELIABLE,
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
)
_MANAGE_TYPE = "nav2_msgs/srv/ManageLifecycleNodes"
_STATE_POLL = 0.5  # seconds between get_state calls (upstream: 2 s)
_REPUBLISH = 1.0  # seconds between initial pose publications while waiting for amcl_pose
_FIRST_REPUBLISH = 0.3  # the first may be lost while discovery completes on the localizer's side


class LocalizationMixin(NavigatorBase):
    initial_pose: PoseStamped
    initial_pose_received: bool
    _amcl_received: threading.Event
    _initial_pose_published_at: float

    def _setup_localization(self) -> None:
        self.initial_pose = PoseStamped()
        self.initial_pose.header.frame_id = "map"
        self.initial_pose_received = False
        self._amcl_received = threading.Event()
        self._initial_pose_published_at = -math.inf
        self.localization_pose_sub = self.create_subscription(
            PoseWithCovarianceStamped, "amcl_pose", self._amclPoseCallback, AMCL_POSE_QOS
        )
        self.initial_pose_pub = self.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)

    def _amclPoseCallback(self, _msg: PoseWithCovarianceStamped) -> None:
        self.debug("Received amcl pose")
        self.initial_pose_received = True
        self._amcl_received.set()

    def setInitialPose(self, initial_pose: PoseStamped) -> None:
        """Tell the localizer where the robot is (published on `initialpose`)."""
        check_pose_stamped(initial_pose, "initial_pose")
        self.clearLastError()
        self.initial_pose_received = False
        self._amcl_received.clear()
        self.initial_pose = initial_pose
        self._setInitialPose()

    def _setInitialPose(self) -> None:
        # A message published before discovery matched the localizer's subscription is lost: wait (bounded) for it.
        wait_until(lambda: self.initial_pose_pub.get_subscription_count() > 0, min(2.0, self.timeouts.server))
        msg = PoseWithCovarianceStamped()
        msg.pose.pose = self.initial_pose.pose
        msg.header.frame_id = self.initial_pose.header.frame_id
        msg.header.stamp = self.initial_pose.header.stamp
        self.info("Publishing Initial Pose")
        self.initial_pose_pub.publish(msg)
        self._initial_pose_published_at = time.monotonic()

    def waitUntilNav2Active(self, navigator: str = "bt_navigator", localizer: str = "amcl") -> None:
        """Wait until the localizer and the navigator report 'active' (and amcl has a pose); bounded."""
        check_name(navigator, "navigator")
        check_name(localizer, "localizer")
        if localizer != "robot_localization":  # not a lifecycle node
            self._waitForNodeToActivate(localizer)
        if localizer == "amcl":
            self._waitForInitialPose()
        self._waitForNodeToActivate(navigator)
        self.info("Nav2 is ready for use!")

    def _waitForNodeToActivate(self, node_name: str) -> None:
        self.debug(f"Waiting for {node_name} to become active..")
        limit = self.timeouts.lifecycle
        deadline = time.monotonic() + limit
        service = f"{node_name}/get_state"
        state = "unknown"
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            try:
                response = self._calls.call(
                    GetState, service, GetState.Request(), server_timeout=remaining, idempotent=True
                )
            except NavigatorTimeout as exc:
                raise NavigatorTimeout(f"{exc} (waiting for '{node_name}' to become active)") from None
            state = response.current_state.label
            self.debug(f"Result of get_state: {state}")
            if state == "active":
                return
            time.sleep(min(_STATE_POLL, max(0.0, deadline - time.monotonic())))
        message = f"'{node_name}' did not become active within {limit:g} s (last state: '{state}')"
        self.error(message)
        raise NavigatorTimeout(message)

    def _waitForInitialPose(self) -> None:
        self._ensure_spun()
        limit = self.timeouts.localization
        deadline = time.monotonic() + limit
        published = 1 if self._initial_pose_published_at > -math.inf else 0
        while not self.initial_pose_received:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                p = self.initial_pose.pose.position
                message = (
                    f"no 'amcl_pose' after {limit:g} s although the initial pose ({p.x:.2f}, {p.y:.2f}) was "
                    f"published {published} times on 'initialpose' in namespace '{self.get_namespace()}' — "
                    "is the localizer running and is the pose inside the map (frame 'map')?"
                )
                self.error(message)
                raise NavigatorTimeout(message)
            period = _FIRST_REPUBLISH if published <= 1 else _REPUBLISH
            since = time.monotonic() - self._initial_pose_published_at
            if since >= period:  # setInitialPose has just published: give that one its chance first
                self.info("Setting initial pose")
                self._setInitialPose()
                published += 1
                since = 0.0
            self.info("Waiting for amcl_pose to be received")
            self._amcl_received.wait(min(period - since, remaining))

    # --- lifecycle managers ------------------------------------------------------------------------------------
    def _lifecycle_managers(self) -> list[str]:
        """Every ManageLifecycleNodes service in our namespace (upstream took every robot's)."""
        ns = self.get_namespace().rstrip("/")

        def find() -> list[str]:
            return sorted(
                name
                for name, types in self.get_service_names_and_types()
                if _MANAGE_TYPE in types and (not ns or name.startswith(ns + "/"))
            )

        found: list[str] = []

        def any_found() -> bool:
            found[:] = find()
            return bool(found)

        if not wait_until(any_found, self.timeouts.server, period=0.1):
            raise NavigatorTimeout(
                f"no {_MANAGE_TYPE} service in namespace '{self.get_namespace()}' after {self.timeouts.server:g} s"
                " — is Nav2 (its lifecycle managers) running?"
            )
        return found

    def _manage(self, command: int, verb: str) -> bool:
        ok = True
        for name in self._lifecycle_managers():
            self.info(f"{verb} {name}")
            request = ManageLifecycleNodes.Request(command=command)
            response = self._calls.call(ManageLifecycleNodes, name, request, response_timeout=self.timeouts.result)
            if not response.success:
                self.error(f"{name} reported failure")
                ok = False
        return ok

    def lifecycleStartup(self) -> bool:
        """STARTUP on every lifecycle manager found by discovery."""
        self.info("Starting up lifecycle nodes based on lifecycle_manager.")
        ok = self._manage(ManageLifecycleNodes.Request.STARTUP, "Starting up")
        if ok:
            self.info("Nav2 is ready for use!")
        return ok

    def lifecycleShutdown(self) -> bool:
        """SHUTDOWN on every lifecycle manager found by discovery."""
        self.info("Shutting down lifecycle nodes based on lifecycle_manager.")
        return self._manage(ManageLifecycleNodes.Request.SHUTDOWN, "Shutting down")
