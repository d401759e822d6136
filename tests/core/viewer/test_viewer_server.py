"""The viewer's web server over a real socket with a fake ROS side: assets, stream, validation, floods, cleanup."""

from __future__ import annotations

import json
import socket
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from websockets.exceptions import InvalidStatus
from websockets.sync.client import ClientConnection, connect

from tb4.viewer.grid_image import Grid
from tb4.viewer.launch import ViewerHandle, start_server_in_thread
from tb4.viewer.protocol import Command, PoseCommand
from tb4.viewer.server import STATIC_DIR
from tb4.viewer.state import ViewerState


class FakeBridge:
    """Stands in for ViewerBridge: one ViewerState per namespace, commands recorded."""

    def __init__(self) -> None:
        self.default_namespace = ""
        self.states: dict[str, ViewerState] = {}
        self.users: dict[str, int] = {}
        self.commands: list[tuple[str, Command]] = []
        self.lock = threading.Lock()
        self.closed = False
        self.initial = ""
        state = self._state("")
        state.set_layer("map", Grid(np.zeros((20, 30), dtype=np.int8), 0.05, -1.0, -0.5))
        state.set_odom_base((0.5, 0.25, 0.0))

    def _state(self, namespace: str) -> ViewerState:
        return self.states.setdefault(namespace, ViewerState(namespace))

    def acquire(self, namespace: str, timeout: float = 10.0, detailed: bool = True) -> ViewerState:
        with self.lock:
            self.users[namespace] = self.users.get(namespace, 0) + 1
            return self._state(namespace)

    def release(self, namespace: str) -> None:
        with self.lock:
            self.users[namespace] -= 1

    def namespaces(self) -> list[str]:
        return sorted(self.states)

    def initial_namespace(self) -> str:
        return self.initial

    def add_fleet(self, namespaces: tuple[str, ...]) -> None:
        """A fleet in one world: each robot announces it and is drawn at its true pose (robot k at y = k)."""
        for k, namespace in enumerate(namespaces, start=1):
            state = self._state(namespace)
            state.set_fleet(namespaces)
            state.set_truth((0.0, float(k), 0.0))
        self.initial = namespaces[0]

    def command(self, namespace: str, command: Command) -> str:
        with self.lock:
            self.commands.append((namespace, command))
        if isinstance(command, PoseCommand) and command.x > 1000:
            raise RuntimeError("no navigate_to_pose server")
        return f"did {command.kind}"

    def close(self, timeout: float = 5.0) -> None:
        self.closed = True


@pytest.fixture
def served() -> Iterator[tuple[ViewerHandle, FakeBridge]]:
    bridge = FakeBridge()
    handle = start_server_in_thread(bridge, port=0)
    yield handle, bridge
    handle.stop()


def _ws_url(handle: ViewerHandle) -> str:
    return handle.url.replace("http://", "ws://") + "ws"


def _next(ws: ClientConnection, kind: str, timeout: float = 10.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = json.loads(ws.recv(timeout=timeout))
        if msg["type"] == kind:
            return msg
    raise AssertionError(f"no {kind!r} message within {timeout} s")


def _health(handle: ViewerHandle) -> dict[str, Any]:
    with urllib.request.urlopen(handle.url + "api/health", timeout=10) as response:
        return json.loads(response.read())


def test_serves_the_page_and_its_assets_from_the_package_on_loopback(served) -> None:
    handle, _ = served
    assert handle.url.startswith("http://127.0.0.1:")
    with urllib.request.urlopen(handle.url, timeout=10) as response:
        html = response.read().decode()
    assert '<script type="module" src="/static/app.js">' in html and "<canvas" in html
    for name in ("app.js", "style.css"):
        with urllib.request.urlopen(handle.url + "static/" + name, timeout=10) as response:
            assert response.status == 200 and len(response.read()) > 500
    modules = sorted(p.relative_to(STATIC_DIR).as_posix() for p in (STATIC_DIR / "js").glob("*.js"))
    assert len(modules) >= 8
    for name in modules:  # browsers run a module only when it comes with a JavaScript MIME type
        with urllib.request.urlopen(handle.url + "static/" + name, timeout=10) as response:
            assert response.status == 200 and "javascript" in response.headers["content-type"], name
    for path in STATIC_DIR.rglob("*.*"):  # no CDN: the page works offline
        text = path.read_text()
        assert "https://" not in text and "http://" not in text, path.name


def test_page_gets_hello_map_layer_and_states(served) -> None:
    handle, _ = served
    with connect(_ws_url(handle)) as ws:
        hello = _next(ws, "hello")
        assert hello["namespace"] == "" and "map" in hello["layers"]
        layer = _next(ws, "layer")
        assert layer["name"] == "map" and (layer["width"], layer["height"]) == (30, 20)
        assert layer["origin"][:2] == [-1.0, -0.5]
        state = _next(ws, "state")
        assert state["robot"]["x"] == 0.5 and state["robot"]["y"] == 0.25


def test_updates_are_sent_at_a_bounded_rate_however_fast_the_state_changes(served) -> None:
    handle, bridge = served
    stop = threading.Event()

    def churn() -> None:  # a simulator at a very high real-time factor
        i = 0
        while not stop.is_set():
            i += 1
            bridge.states[""].set_odom_base((i * 1e-4, 0.0, 0.0))
            bridge.states[""].set_sim_time(i * 0.01)

    thread = threading.Thread(target=churn, daemon=True)
    thread.start()
    try:
        with connect(_ws_url(handle)) as ws:
            _next(ws, "state")
            start, states = time.monotonic(), 0
            while time.monotonic() - start < 1.5:
                if json.loads(ws.recv(timeout=10))["type"] == "state":
                    states += 1
    finally:
        stop.set()
        thread.join()
    assert 1 <= states <= 20  # 10 per second by default; never one per change


def test_malformed_messages_are_rejected_and_the_page_keeps_working(served) -> None:
    handle, bridge = served
    with connect(_ws_url(handle)) as ws:
        _next(ws, "hello")
        for bad in ("not json", '{"type": "goal", "x": NaN, "y": 0, "yaw": 0}', '{"type": "fly"}', b"\x00\x01"):
            ws.send(bad)
            error = _next(ws, "error")
            assert error["message"].startswith("rejected:")
        ws.send(json.dumps({"type": "initial_pose", "x": 1.0, "y": 2.0, "yaw": 0.5}))
        ack = _next(ws, "ack")
        assert ack["command"] == "initial_pose" and ack["pose"] == {"x": 1.0, "y": 2.0, "yaw": 0.5}
        ws.send(json.dumps({"type": "goal", "x": 5000.0, "y": 0.0, "yaw": 0.0}))  # the ROS side refuses
        assert "no navigate_to_pose server" in _next(ws, "error")["message"]
        assert _next(ws, "state")["robot"] is not None
    assert [c.kind for _, c in bridge.commands] == ["initial_pose", "goal"]  # nothing malformed got through


def test_a_flood_is_limited_with_a_message_and_the_connection_survives(served) -> None:
    handle, bridge = served
    with connect(_ws_url(handle)) as ws:
        _next(ws, "hello")
        for _ in range(200):
            ws.send('{"type": "cancel"}')
        assert "too many messages" in _next(ws, "error")["message"]
        assert _next(ws, "state")["type"] == "state"
    assert 1 <= len(bridge.commands) <= 60  # the burst and the refill, not 200


def test_oversized_messages_are_rejected(served) -> None:
    handle, _ = served
    with connect(_ws_url(handle)) as ws:
        _next(ws, "hello")
        ws.send(json.dumps({"type": "cancel", "pad": "x" * 10000}))
        assert "too long" in _next(ws, "error")["message"]


def test_switching_namespace_and_closing_the_tab_release_everything(served) -> None:
    handle, bridge = served
    with connect(_ws_url(handle)) as ws:
        _next(ws, "hello")
        ws.send(json.dumps({"type": "namespace", "namespace": "robot2"}))
        hello = _next(ws, "hello")
        assert hello["namespace"] == "/robot2"
        assert _next(ws, "state")["namespace"] == "/robot2"
        assert _health(handle)["pages"] == 1
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and (_health(handle)["pages"] or any(bridge.users.values())):
        time.sleep(0.05)
    assert _health(handle)["pages"] == 0
    assert bridge.users == {"": 0, "/robot2": 0}
    with connect(_ws_url(handle)) as ws:  # and the server still serves new pages
        assert _next(ws, "hello")["namespace"] == ""


def _state_where(ws: ClientConnection, check: Any, what: str, timeout: float = 10.0) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        state = _next(ws, "state", timeout)
        if check(state):
            return state
    raise AssertionError(f"no state with {what} within {timeout} s")


def test_a_fleet_page_commands_one_robot_draws_the_others_and_picks_another(served) -> None:
    handle, bridge = served
    fleet = ("/robot1", "/robot2", "/robot3")
    bridge.add_fleet(fleet)
    with connect(_ws_url(handle)) as ws:
        assert _next(ws, "hello")["namespace"] == "/robot1"  # no namespace asked for: the fleet's first robot
        state = _state_where(ws, lambda s: len(s["fleet"]) == 3, "the whole fleet")
        assert [r["namespace"] for r in state["fleet"]] == list(fleet)
        assert state["fleet"][0] == {"namespace": "/robot1", "picked": True}
        assert [(r["robot"]["y"], r["robot"]["frame"]) for r in state["fleet"][1:]] == [(2.0, "truth"), (3.0, "truth")]
        assert state["robot"]["y"] == 1.0
        ws.send(json.dumps({"type": "goal", "x": 1.0, "y": 2.0, "yaw": 0.0}))
        _next(ws, "ack")
        ws.send(json.dumps({"type": "namespace", "namespace": "/robot2"}))
        assert _next(ws, "hello")["namespace"] == "/robot2"
        state = _state_where(ws, lambda s: s["namespace"] == "/robot2" and len(s["fleet"]) == 3, "robot 2 picked")
        assert [r.get("picked", False) for r in state["fleet"]] == [False, True, False]
        assert state["fleet"][0]["robot"]["y"] == 1.0  # the robot left is still drawn
        ws.send(json.dumps({"type": "goal", "x": 3.0, "y": 4.0, "yaw": 0.0}))
        _next(ws, "ack")
    assert [(ns, c.kind) for ns, c in bridge.commands] == [("/robot1", "goal"), ("/robot2", "goal")]
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(bridge.users.values()):
        time.sleep(0.05)
    assert all(users == 0 for users in bridge.users.values()), bridge.users  # every acquisition released


def test_fleet_robots_whose_own_fleet_message_is_late_are_not_drawn_at_their_odometry(served) -> None:
    handle, bridge = served
    fleet = ("/robot1", "/robot2", "/robot3")
    bridge.add_fleet(fleet[:1])
    bridge.states["/robot1"].set_fleet(fleet)  # robot 1 names the fleet; robots 2 and 3 have said nothing yet
    for namespace in fleet[1:]:
        bridge._state(namespace).set_odom_base((0.0, 0.0, 0.0))  # each odom frame starts on the robot's own dock
    with connect(_ws_url(handle)) as ws:
        state = _state_where(ws, lambda s: len(s["fleet"]) == 3, "the whole fleet")
        assert [r["robot"] for r in state["fleet"][1:]] == [None, None]  # not stacked on robot 1's dock
        for k, namespace in enumerate(fleet[1:], start=2):
            bridge.states[namespace].set_truth((0.0, float(k), 0.0))
        state = _state_where(ws, lambda s: all(r.get("picked") or r["robot"] for r in s["fleet"]), "robots 2, 3")
        assert [(r["robot"]["y"], r["robot"]["frame"]) for r in state["fleet"][1:]] == [(2.0, "truth"), (3.0, "truth")]


def test_websockets_from_other_sites_are_refused(served) -> None:
    handle, bridge = served
    with pytest.raises(InvalidStatus), connect(_ws_url(handle), origin="http://evil.example") as ws:
        ws.recv(timeout=5)
    host = handle.url.split("//")[1].rstrip("/")
    with connect(_ws_url(handle), origin=f"http://{host}") as ws:
        assert _next(ws, "hello")["type"] == "hello"
    assert bridge.commands == []


def test_stop_closes_the_bridge_and_frees_the_port() -> None:
    bridge = FakeBridge()
    handle = start_server_in_thread(bridge, port=0)
    port = int(handle.url.rsplit(":", 1)[1].strip("/"))
    handle.stop()
    assert bridge.closed and not handle.running
    again = start_server_in_thread(FakeBridge(), port=port)  # the port is reusable at once
    again.stop()


def _handshake(handle: ViewerHandle, host: str, origin: str | None = None, path: str = "/ws") -> int:
    """A raw WebSocket handshake with the Host (and Origin) a browser would send: its HTTP status."""
    port = int(handle.url.split(":")[2].split("/")[0])
    lines = [
        f"GET {path} HTTP/1.1",
        f"Host: {host}",
        "Upgrade: websocket",
        "Connection: Upgrade",
        "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
        "Sec-WebSocket-Version: 13",
    ]
    if origin is not None:
        lines.append(f"Origin: {origin}")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as sock:
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        status_line = sock.makefile("rb").readline().decode()
    return int(status_line.split()[1])


def _get(handle: ViewerHandle, path: str, host: str | None = None, cookie: str | None = None) -> tuple[int, Any]:
    request = urllib.request.Request(handle.url.split("?")[0].rstrip("/") + path)
    if host is not None:
        request.add_header("Host", host)
    if cookie is not None:
        request.add_header("Cookie", cookie)
    try:
        with urllib.request.urlopen(request, timeout=10) as response:
            return response.status, response.headers
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers


def test_a_rebound_domain_gets_neither_state_nor_commands_in(served) -> None:
    """DNS rebinding: the page's Origin matches its Host, but the Host is not a name the viewer serves."""
    handle, bridge = served
    port = handle.url.split(":")[2].split("/")[0]
    assert _handshake(handle, f"evil.example:{port}", origin=f"http://evil.example:{port}") == 403
    assert _handshake(handle, f"evil.example:{port}") == 403  # no Origin either: still not a name served here
    assert _handshake(handle, f"127.0.0.1.evil.example:{port}", origin=f"http://127.0.0.1.evil.example:{port}") == 403
    for path in ("/", "/api/health", "/static/app.js"):
        assert _get(handle, path, host=f"evil.example:{port}")[0] == 403
    assert bridge.users == {} and bridge.commands == []  # refused before any state was taken or command read


def test_loopback_names_are_served_and_a_wrong_origin_is_still_refused(served) -> None:
    handle, bridge = served
    port = handle.url.split(":")[2].split("/")[0]
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", f"[::1]:{port}", f"127.0.0.2:{port}", "localhost"):
        assert _handshake(handle, host, origin=f"http://{host}") == 101, host
        assert _get(handle, "/api/health", host=host)[0] == 200, host
    assert _handshake(handle, f"localhost:{port}", origin=f"http://evil.example:{port}") == 403


def test_allowed_host_names_are_served_and_no_others() -> None:
    handle = start_server_in_thread(FakeBridge(), port=0, allow_hosts=["viewer.lab"])
    try:
        port = handle.url.split(":")[2].split("/")[0]
        assert _handshake(handle, f"viewer.lab:{port}", origin=f"http://viewer.lab:{port}") == 101
        assert _handshake(handle, f"VIEWER.LAB.:{port}") == 101  # names compare as DNS does
        assert _handshake(handle, f"other.lab:{port}") == 403
    finally:
        handle.stop()


def test_a_token_viewer_refuses_requests_without_its_token() -> None:
    bridge = FakeBridge()
    handle = start_server_in_thread(bridge, port=0, token=True)
    try:
        assert "?token=" in handle.url
        token = handle.url.split("?token=")[1]
        port = handle.url.split(":")[2].split("/")[0]
        host = f"127.0.0.1:{port}"
        assert _handshake(handle, host) == 403
        assert _handshake(handle, host, path="/ws?token=wrong" + token) == 403
        assert _get(handle, "/api/health")[0] == 403
        assert bridge.users == {}
        assert _handshake(handle, host, path=f"/ws?token={token}") == 101
        status, headers = _get(handle, f"/?token={token}")
        assert status == 200
        cookie = headers["set-cookie"].split(";")[0]
        assert f"_{port}=" in cookie and "HttpOnly" in headers["set-cookie"]
        assert _get(handle, "/api/health", cookie=cookie)[0] == 200  # a reload carries the cookie
        assert _get(handle, "/api/health", cookie=cookie + "x")[0] == 403
        assert _get(handle, "/api/health", host=f"evil.example:{port}", cookie=cookie)[0] == 403  # token + bad Host
    finally:
        handle.stop()
