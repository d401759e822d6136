"""GPS in the simulator: follow_gps_waypoints on the waypoint_follower, and gps/fix from the true pose.

GeoPose goals become map poses through the world's datum on a local tangent plane (tb4.nav.geodesy), as Nav2's
waypoint follower does through robot_localization's fromLL; the orientation is copied unchanged. A waypoint that
cannot be converted is skipped (all of them with stop_on_failure), so a goal left without waypoints fails with
NO_WAYPOINTS_GIVEN; the rest is follow_waypoints: a waypoint off the map is missed with its navigation error.
"""

from __future__ import annotations

import math
from typing import Any

from nav2_msgs import action as nav2_action
from sensor_msgs.msg import NavSatFix, NavSatStatus

from tb4.nav.geodesy import Datum, GeodesyError
from tb4.ros.action_bridge import ImmediateTask
from tb4.ros.convert import quaternion_to_yaw, time_msg
from tb4.wire import result_code

__all__ = ["GpsInterfaces", "GPS_RATE", "GPS_STDDEV"]

GPS_RATE = 5.0  # Hz of gps/fix
GPS_STDDEV = 0.02  # m reported in the fix covariance: the fix is the true pose


class GpsInterfaces:
    """follow_gps_waypoints on `nav2`'s waypoint_follower, gps/fix on `node` (the robot's node)."""

    def __init__(self, nav2: Any, node: Any, datum: tuple[float, float, float] | None) -> None:
        self.nav2 = nav2
        self.loop = nav2.loop
        self.datum = Datum(*datum) if datum is not None else None
        self.fix_pub = node.create_publisher(NavSatFix, "gps/fix", 10)
        A = nav2_action
        nav2.serve_action(
            "waypoint_follower",
            A.FollowGPSWaypoints,
            "follow_gps_waypoints",
            self._follow,
            invalid_code=A.FollowGPSWaypoints.Result.UNKNOWN,
        )
        if self.datum is not None:
            self.loop.every(1.0 / GPS_RATE, self._publish_fix)

    def to_map(self, geopose: Any) -> tuple[float, float, float]:
        """GeoPose -> (x, y, yaw) in the map frame; GeodesyError when it cannot be converted."""
        if self.datum is None:
            raise GeodesyError("this world has no GPS datum")
        p, q = geopose.position, geopose.orientation
        x, y = self.datum.to_map(float(p.latitude), float(p.longitude), float(p.altitude))
        yaw = quaternion_to_yaw(q)
        if not math.isfinite(yaw):
            raise GeodesyError(f"orientation is not a finite quaternion: {q}")
        return (x, y, yaw)

    def _follow(self, goal: Any) -> Any:
        wf = self.nav2.nav.params.waypoint_follower
        poses, problems = [], []
        for i, geopose in enumerate(goal.gps_poses):
            try:
                poses.append(self.to_map(geopose))
            except GeodesyError as exc:
                problems.append(f"waypoint {i}: {exc}")
                self.nav2.nodes["waypoint_follower"].get_logger().error(f"could not convert GPS waypoint {i}: {exc}")
                if wf["stop_on_failure"]:
                    poses = []
                    break
        if not poses:
            why = "; ".join(problems) or "no waypoints given"
            return ImmediateTask(
                False,
                {
                    "error_code": result_code(nav2_action.FollowGPSWaypoints, "NO_WAYPOINTS_GIVEN"),
                    "error_msg": f"empty vector of waypoints after GPS conversion ({why})",
                },
            )
        self._announce(poses)
        return self.nav2.loop.inputs.nav.start_follow_waypoints(poses, int(goal.number_of_loops), int(goal.goal_index))

    def _announce(self, poses: list[tuple[float, float, float]]) -> None:
        """The converted waypoints on `goals`, as follow_waypoints announces its own (viewers and recordings)."""
        self.nav2.navigation.announce(poses)

    def _publish_fix(self, now: float) -> None:
        if self.datum is None or self.fix_pub.get_subscription_count() == 0:
            return
        pose = self.loop.sim.pose()
        lat, lon, alt = self.datum.from_map(pose.x, pose.y)
        msg = NavSatFix()
        msg.header.frame_id = "gps_link"
        msg.header.stamp = time_msg(now)
        msg.status.status = NavSatStatus.STATUS_FIX
        msg.status.service = NavSatStatus.SERVICE_GPS
        msg.latitude, msg.longitude, msg.altitude = lat, lon, alt
        var = GPS_STDDEV**2
        msg.position_covariance = [var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, var]
        msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
        self.fix_pub.publish(msg)
