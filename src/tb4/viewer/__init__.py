"""The live web viewer: a browser page that shows the ROS graph like RViz and offers its navigation tools.

`tb4 view` (or `start_viewer_in_thread`) runs a small Starlette server; a rclpy node (bridge.py) keeps the newest
value of every topic the page shows, and each open page gets a bounded-rate stream of snapshots over a WebSocket.
state.py and protocol.py are plain Python (no rclpy) so they are unit-tested without DDS.
"""

from __future__ import annotations

__all__ = ["start_viewer_in_thread", "ViewerHandle"]


def __getattr__(name: str) -> object:
    # Lazy: importing tb4.viewer must not pull rclpy or uvicorn in (e.g. for `tb4 --help`).
    if name in __all__:
        from tb4.viewer import server

        return getattr(server, name)
    raise AttributeError(name)
