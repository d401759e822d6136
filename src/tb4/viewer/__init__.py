"""The live web viewer: a browser page that shows the ROS graph like RViz and offers its navigation tools.

`tb4 view` (or `start_viewer_in_thread`, launch.py) runs a small Starlette server (server.py); rclpy nodes
(bridge.py, robot_bridge.py) keep the newest value of every topic the page shows in a ViewerState (state.py), and
each open page gets a bounded-rate stream of snapshots over a WebSocket. state.py, tracking.py, grid_image.py,
world_info.py and protocol.py are plain Python (no rclpy), unit-tested without DDS.
"""

from __future__ import annotations

__all__ = ["start_viewer_in_thread", "ViewerHandle"]


def __getattr__(name: str) -> object:
    # Lazy: importing tb4.viewer must not pull rclpy or uvicorn in (e.g. for `tb4 --help`).
    if name in __all__:
        from tb4.viewer import launch

        return getattr(launch, name)
    raise AttributeError(name)
