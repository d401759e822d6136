"""The amcl node's ROS surface, as Nav2's amcl offers it; the filter itself is tb4.nav.amcl in the core.

Topics: `initialpose` in (geometry_msgs/PoseWithCovarianceStamped, its covariance seeds the filter), `amcl_pose`
out (latched, with covariance) and `particle_cloud` out (nav2_msgs/ParticleCloud; reliable, so both QoS
profiles subscribe).
Services: `reinitialize_global_localization` and `request_nomotion_update` (std_srvs/Empty) and
`set_initial_pose` (nav2_msgs/SetInitialPose). map->odom goes out on tf with the odometry (tb4.ros.create3_interfaces).
Bad input is logged and ignored; nothing here can stop the simulator.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any

import numpy as np
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav2_msgs.msg import Particle, ParticleCloud
from nav2_msgs.srv import SetInitialPose
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_srvs.srv import Empty as EmptySrv

from tb4.nav.amcl import Amcl
from tb4.ros.convert import StampedSerialization, checked_pose, pose_msg, time_msg
from tb4.ros.loop import LoopView
from tb4.ros.qos import LATCHED
from tb4.ros.replies import create_service
from tb4.ros.robot.common import Throttle

__all__ = ["AmclInterfaces", "initial_pose_from_msg"]

AMCL_POSE_PERIOD = 0.5  # s of sim time between amcl_pose messages when the filter is idle
CLOUD_PERIOD = 0.5  # s between particle clouds
MAX_CLOUD = 5000  # particles per cloud message at most (an even subsample of a larger set, e.g. after a reinit)


def initial_pose_from_msg(msg: PoseWithCovarianceStamped) -> tuple[float, float, float, np.ndarray]:
    """(x, y, yaw, 3x3 covariance) from an initial pose; ValueError with the reason when unusable.

    The message's covariance is used as is, as Nav2's amcl does: RViz's 2D Pose Estimate sends a spread, while
    BasicNavigator.setInitialPose sends zeros (every particle starts at the given pose)."""
    x, y, yaw = checked_pose(msg.pose.pose, "initial pose")
    if msg.header.frame_id not in ("", "map"):
        raise ValueError(f"initial pose must be in frame 'map', got '{msg.header.frame_id}'")
    full = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
    if not np.all(np.isfinite(full)):
        raise ValueError("initial pose covariance must be finite")
    idx = [0, 1, 5]
    cov = full[np.ix_(idx, idx)]
    cov = 0.5 * (cov + cov.T)
    if np.any(np.linalg.eigvalsh(cov) < -1e-9) or np.any(np.diag(cov) > 1e6):
        raise ValueError("initial pose covariance must be positive semi-definite and below 1e6")
    return (x, y, yaw, cov)


# Nav2's amcl sends the cloud best effort; reliable reaches both a default (reliable) and a sensor-data subscriber,
# and a depth of 2 keeps a slow viewer from queueing old clouds.
RELIABLE_LATEST = QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE)


class AmclInterfaces:
    """Wires the amcl node to the loop's NavigationCore; `states` is the lifecycle table of the Nav2 nodes."""

    def __init__(self, node: Node, loop: LoopView, states: dict[str, str], group: CallbackGroup) -> None:
        self.node = node
        self.loop = loop
        self.nav = loop.nav
        self.states = states
        self.pose_pub = node.create_publisher(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
        self.cloud_pub = node.create_publisher(ParticleCloud, "particle_cloud", RELIABLE_LATEST)
        node.create_subscription(PoseWithCovarianceStamped, "initialpose", self._on_initial_pose, 10)
        create_service(node, EmptySrv, "reinitialize_global_localization", self._on_global, callback_group=group)
        create_service(node, EmptySrv, "request_nomotion_update", self._on_nomotion, callback_group=group)
        create_service(node, SetInitialPose, "set_initial_pose", self._on_set_initial_pose, callback_group=group)
        self._last_update: float | None = None
        self._last_pose_time = -math.inf
        pose = PoseWithCovarianceStamped()
        pose.header.frame_id = "map"
        self._pose = StampedSerialization(pose)  # an idle filter: the same estimate every AMCL_POSE_PERIOD
        self._throttle = Throttle()
        #: called with the stamp of every amcl_pose sent (the ground truth goes out beside it)
        self.on_pose: list[Callable[[float], None]] = []
        loop.every(0.1, self._tick)
        loop.every(CLOUD_PERIOD, self.publish_cloud)
        loop.on_reset(self._on_reset)

    def _on_reset(self) -> None:
        """A world reset: no estimate until a new initial pose. amcl_pose is latched, so its publisher is made
        again: a client of the new run must not take the last run's estimate for the answer to its initial pose
        (the navigator's waitUntilNav2Active waits for amcl_pose)."""
        self._last_update = None
        self._last_pose_time = -math.inf
        self.node.destroy_publisher(self.pose_pub)
        self.pose_pub = self.node.create_publisher(PoseWithCovarianceStamped, "amcl_pose", LATCHED)

    # --- inputs ----------------------------------------------------------------------------------------------
    def _active(self, what: str) -> bool:
        if self.states.get("amcl") != "active":
            self.node.get_logger().warn(f"{what} ignored: amcl is not active")
            return False
        return True

    def set_initial_pose(self, msg: PoseWithCovarianceStamped, what: str) -> bool:
        try:
            x, y, yaw, cov = initial_pose_from_msg(msg)
        except ValueError as exc:
            self.node.get_logger().warn(f"{what} ignored: {exc}")
            return False
        if not self._active(what):
            return False
        try:
            self.loop.inputs.nav.set_initial_pose(x, y, yaw, cov=cov)
        except ValueError as exc:
            self.node.get_logger().warn(f"{what} ignored: {exc}")
            return False
        # not a release of the start-up hold: the wait for amcl_pose and Nav2 that follows is still start-up
        self.node.get_logger().info(f"initial pose set to ({x:.2f}, {y:.2f}, {math.degrees(yaw):.0f} deg)")
        self.publish_pose(self.loop.sim.time)
        return True

    def _on_initial_pose(self, msg: PoseWithCovarianceStamped) -> None:
        self.set_initial_pose(msg, "initialpose")

    def _on_set_initial_pose(self, request: Any, response: Any) -> Any:
        self.set_initial_pose(request.pose, "set_initial_pose")
        return response

    def _on_global(self, _request: Any, response: Any) -> Any:
        if not self._active("reinitialize_global_localization"):
            return response
        try:
            self.loop.inputs.nav.global_localization()
        except ValueError as exc:
            self.node.get_logger().warn(f"reinitialize_global_localization refused: {exc}")
            return response
        self.loop.release()
        self.node.get_logger().info("global localization: particles spread over the free space of the map")
        return response

    def _on_nomotion(self, _request: Any, response: Any) -> Any:
        if self._active("request_nomotion_update") and not self.loop.inputs.nav.request_nomotion_update():
            self.node.get_logger().warn("request_nomotion_update ignored: the simulator does not run amcl")
        return response

    # --- outputs ---------------------------------------------------------------------------------------------
    def _tick(self, now: float) -> None:
        """amcl_pose after every filter update (as Nav2), and every AMCL_POSE_PERIOD otherwise."""
        last = self.nav.localizer.last_update
        if last != self._last_update:
            self._last_update = last
            self.publish_pose(now)
        elif now - self._last_pose_time >= AMCL_POSE_PERIOD - 1e-9:
            self.publish_pose(now, idle=True)

    def publish_pose(self, now: float, idle: bool = False) -> None:
        """amcl_pose now; `idle`: the filter has not updated, and a repeat of the last estimate goes out at most
        50 times a wall second (a robot charging for hours at --rate max)."""
        with self.loop.lock:
            pose = self.nav.pose()
            cov = self.nav.localizer.covariance()
        if pose is None:
            return
        self._last_pose_time = now
        x, y, yaw = (float(v) for v in pose)
        covariance = list(map(float, cov))
        key = struct.pack(f"3d{len(covariance)}d", x, y, yaw, *covariance)
        if idle and self._throttle.repeat_too_soon("amcl_pose", self._pose.repeats(key)):
            return

        def fill(msg: PoseWithCovarianceStamped) -> None:
            msg.pose.pose = pose_msg(x, y, yaw)
            msg.pose.covariance = covariance

        self.pose_pub.publish(self._pose.serialized(now, key, fill))
        for hook in self.on_pose:
            hook(now)

    def publish_cloud(self, now: float) -> None:
        loc = self.nav.localizer
        if not isinstance(loc, Amcl) or not loc.is_localized or self.cloud_pub.get_subscription_count() == 0:
            return
        with self.loop.lock:
            poses, weights = loc.particles()
        msg = ParticleCloud()
        msg.header.frame_id = "map"
        msg.header.stamp = time_msg(now)
        stride = -(-len(poses) // MAX_CLOUD)  # ceil: every stride-th particle, spread over the whole set
        msg.particles = [
            Particle(pose=pose_msg(float(p[0]), float(p[1]), float(p[2])), weight=float(w))
            for p, w in zip(poses[::stride], weights[::stride], strict=True)
        ]
        self.cloud_pub.publish(msg)
