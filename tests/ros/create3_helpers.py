"""Shared by the Create 3 API tests: a test world with a wall and a cliff, odometry helpers, hazard reading."""

from __future__ import annotations

import math
from pathlib import Path

from tb4.sim.world import WORLDS_DIR

SUCCEEDED, CANCELED, ABORTED, REJECTED = 4, 5, 6, -1

# Open floor of the depot map around (-6, -1); a wall (an obstacle, not in the map) 2 m east of the start, a long
# wall along y = 0.9 (north of the start, for wall following) and a cliff (a floor drop, which the lidar does not
# see) whose edge is 2.5 m west of the start.
LAB_WORLD = f"""
name: create3_lab
map: {WORLDS_DIR / "depot_map.yaml"}
dock: [0.0, 0.0, 0.0]
start: [-6.0, -1.0, 0]
obstacles:
  - {{shape: box, position: [-3.9, -1.0], size: [0.2, 1.6], heading: 0}}
  - {{shape: box, position: [-6.0, 1.0], size: [6.0, 0.2], heading: 0}}
cliffs:
  - {{shape: box, position: [-9.0, -1.0], size: [1.0, 3.0]}}
"""
WALL_X = -4.0  # the wall's face towards the start
CLIFF_EDGE_X = -8.5
LONG_WALL_Y = 0.9  # its face towards the start


def lab_world(tmp_path: Path) -> str:
    path = tmp_path / "create3_lab.yaml"
    path.write_text(LAB_WORLD)
    return str(path)


def yaw_of(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def odom_xy_yaw(msg) -> tuple[float, float, float]:
    p = msg.pose.pose.position
    return (p.x, p.y, yaw_of(msg.pose.pose.orientation))


def hazards(msg) -> set[tuple[int, str]]:
    return {(d.type, d.header.frame_id) for d in msg.detections}


def call(ros, srv_type, name: str, request, attempts: int = 3, timeout: float = 5.0):
    """An idempotent service call, asked again when the reply is lost (a reply can be lost to the DDS discovery
    race while the server has not yet matched the client's reply reader)."""
    from tb4.core.waits import WaitTimeout, wait_for_future

    client = ros.node.create_client(srv_type, name)
    if not client.wait_for_service(timeout_sec=20.0):
        raise WaitTimeout(f"no service '{name}' after 20 s")
    for attempt in range(attempts):
        try:
            return wait_for_future(client.call_async(request), timeout, f"response of {name}")
        except WaitTimeout:
            if attempt == attempts - 1:
                raise
    raise AssertionError("unreachable")
