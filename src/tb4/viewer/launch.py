"""Starting the viewer: bind the listening socket, serve the app (server.py) from a background thread, and stop
it again. `start_viewer_in_thread` starts everything (ROS bridge and web server): `tb4 view`, `tb4 sim --view`,
`tb4 run --view`.
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterable
from typing import Any
from urllib.parse import quote

from tb4.viewer.access import TOKEN_PARAMETER, is_loopback, policy_for
from tb4.viewer.server import UPDATE_RATE, BridgeLike, create_app

__all__ = ["ViewerHandle", "start_viewer_in_thread", "start_server_in_thread", "bind_socket", "is_loopback"]


def bind_socket(host: str, port: int) -> socket.socket:
    """Bind the listening socket ourselves, so port 0 works and the URL is known before serving."""
    infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    family, _, _, _, address = infos[0]
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind(address)
    except OSError as exc:
        sock.close()
        raise OSError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
    sock.listen(64)
    sock.setblocking(False)
    return sock


class ViewerHandle:
    """A viewer serving in a background thread: `.url` to open, `.stop()` to end it (and its ROS node)."""

    def __init__(self, server: Any, thread: threading.Thread, url: str, bridge: BridgeLike | None) -> None:
        self._server = server
        self._thread = thread
        self.url = url
        self.bridge = bridge

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def stop(self, timeout: float = 5.0) -> None:
        self._server.should_exit = True
        self._thread.join(timeout=timeout)
        if self._thread.is_alive():
            self._server.force_exit = True
            self._thread.join(timeout=timeout)
        if self.bridge is not None:
            self.bridge.close()
            self.bridge = None

    def __enter__(self) -> ViewerHandle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _url(host: str, port: int, token: str | None) -> str:
    shown = "127.0.0.1" if host in ("0.0.0.0", "") else ("localhost" if host == "::" else host)
    if ":" in shown:
        shown = f"[{shown}]"
    query = f"?{TOKEN_PARAMETER}={quote(token)}" if token else ""
    return f"http://{shown}:{port}/{query}"


def start_server_in_thread(
    bridge: BridgeLike,
    port: int = 8765,
    host: str = "127.0.0.1",
    update_rate: float = UPDATE_RATE,
    allow_hosts: Iterable[str] = (),
    token: bool | None = None,
) -> ViewerHandle:
    """Serve `bridge` on host:port from a daemon thread; returns once it accepts requests.

    Args:
        bridge: the ROS side.
        port: the port (0: any free one; the handle's url names it).
        host: the address to listen on.
        update_rate: state messages per second to each page.
        allow_hosts: Host names to answer to besides loopback's and `host`'s (a proxy, a DNS alias).
        token: require a per-launch token (default: only beyond loopback); the handle's url carries it.

    Returns:
        The running viewer's ViewerHandle.

    Raises:
        OSError: the address cannot be listened on.
        RuntimeError: the server did not start within 10 s.
    """
    import uvicorn

    sock = bind_socket(host, port)
    actual_port = int(sock.getsockname()[1])
    policy = policy_for(host, actual_port, allow_hosts, token)
    config = uvicorn.Config(
        create_app(bridge, update_rate, policy),
        log_level="warning",
        access_log=False,
        ws="websockets-sansio",
        ws_max_size=65536,
        ws_max_queue=16,
        lifespan="off",
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, kwargs={"sockets": [sock]}, name="tb4-viewer-http", daemon=True)
    thread.start()
    deadline = time.monotonic() + 10.0
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            server.should_exit = True
            sock.close()
            raise RuntimeError(f"the viewer's web server did not start on {host}:{actual_port}")
        time.sleep(0.02)
    return ViewerHandle(server, thread, _url(host, actual_port, policy.token), bridge)


def start_viewer_in_thread(
    namespace: str = "",
    port: int = 8765,
    host: str = "127.0.0.1",
    world: str | None = None,
    update_rate: float = UPDATE_RATE,
    allow_hosts: Iterable[str] = (),
) -> ViewerHandle:
    """Start the whole viewer (its ROS node and web server) in background threads of this process.

    `world` (a world name or file) shows that world's dock and named destinations; without it the viewer shows the
    world the simulator announces on `world` (none on a real robot). Used by `tb4 view`, `tb4 sim --view`,
    `tb4 run --view`.
    """
    from tb4.core.robot_params import load_robot_params
    from tb4.sim.world import load_world
    from tb4.viewer.protocol import normalize_namespace

    ns = normalize_namespace(namespace)  # ProtocolError (a ValueError) before anything starts
    loaded = load_world(world) if world is not None else None
    from tb4.viewer.bridge import ViewerBridge  # rclpy only from here on
    from tb4.viewer.world_info import world_info

    info = world_info(loaded) if loaded is not None else None
    bridge = ViewerBridge(ns, world=info, robot_radius=load_robot_params().drive.radius)
    try:
        return start_server_in_thread(bridge, port=port, host=host, update_rate=update_rate, allow_hosts=allow_hosts)
    except BaseException:
        bridge.close()
        raise
