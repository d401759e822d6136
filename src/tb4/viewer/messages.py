"""ROS messages the viewer reads, turned into the plain values ViewerState holds (numbers, tuples, dicts)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from nav_msgs.msg import OccupancyGrid
from sensor_msgs.msg import BatteryState

from tb4.ros.convert import duration_to_seconds, quaternion_to_yaw
from tb4.viewer.grid_image import Grid

__all__ = ["grid_from_msg", "pose_of", "battery_values", "feedback_values", "waypoint_statuses", "goal_uuid"]

_CHARGING = {
    BatteryState.POWER_SUPPLY_STATUS_CHARGING: "charging",
    BatteryState.POWER_SUPPLY_STATUS_DISCHARGING: "discharging",
    BatteryState.POWER_SUPPLY_STATUS_FULL: "full",
    BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING: "not charging",
}


def grid_from_msg(msg: OccupancyGrid) -> Grid:
    """An OccupancyGrid as a Grid; ValueError when its data does not fill width x height."""
    info = msg.info
    data = np.frombuffer(msg.data, dtype=np.int8) if len(msg.data) else np.zeros(0, dtype=np.int8)
    if info.width == 0 or info.height == 0 or data.size != info.width * info.height:
        raise ValueError(f"grid of {data.size} cells does not match {info.width} x {info.height}")
    origin = info.origin
    return Grid(
        data=data.reshape(info.height, info.width).copy(),
        resolution=float(info.resolution),
        origin_x=float(origin.position.x),
        origin_y=float(origin.position.y),
        frame=msg.header.frame_id or "map",
        origin_yaw=quaternion_to_yaw(origin.orientation),
    )


def pose_of(pose: Any) -> tuple[float, float, float]:
    """(x, y, yaw) of a geometry_msgs Pose."""
    return (float(pose.position.x), float(pose.position.y), quaternion_to_yaw(pose.orientation))


def battery_values(msg: BatteryState) -> dict[str, Any]:
    pct, volts = float(msg.percentage), float(msg.voltage)
    return {
        "percentage": round(pct, 4) if math.isfinite(pct) else None,
        "status": _CHARGING.get(msg.power_supply_status, "unknown"),
        "voltage": round(volts, 2) if math.isfinite(volts) else None,
    }


def feedback_values(action: str, feedback: Any) -> dict[str, Any]:
    """What the page shows of a navigation action's feedback (follow_waypoints has only the waypoint index)."""
    if action == "follow_waypoints":
        return {"current_waypoint": int(feedback.current_waypoint)}
    values = {
        "distance_remaining": round(float(feedback.distance_remaining), 2),
        "eta": round(duration_to_seconds(feedback.estimated_time_remaining), 1),
        "navigation_time": round(duration_to_seconds(feedback.navigation_time), 1),
        "recoveries": int(feedback.number_of_recoveries),
    }
    if action == "navigate_through_poses":
        values["poses_remaining"] = int(feedback.number_of_poses_remaining)
    return values


def waypoint_statuses(feedback: Any) -> list[dict[str, Any]]:
    """navigate_through_poses' waypoints with their status (Kilted's feedback; Jazzy's has none)."""
    waypoints = []
    for w in getattr(feedback, "waypoint_statuses", ()):
        x, y, yaw = pose_of(w.waypoint_pose.pose)
        waypoints.append({"x": round(x, 3), "y": round(y, 3), "yaw": round(yaw, 3), "status": int(w.waypoint_status)})
    return waypoints


def goal_uuid(goal_id: Any) -> str:
    return bytes(goal_id.uuid).hex()
