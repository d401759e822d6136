"""The viewer's web server: the page's files, and one WebSocket per page with a bounded rate of snapshots.

Each page gets at most `update_rate` state messages per second whatever the simulator's speed, grid layers only
when they changed (and at most as often as state.LAYERS allows), and nothing is queued for it: a slow page simply
gets fewer, newer snapshots. Commands from the page are validated (protocol.py) and rate-limited before they
reach ROS. Requests whose Host the viewer does not serve, or without the launch's token where one is needed, are
refused before they reach it (access.py: DNS rebinding); WebSockets opened by other sites' pages are refused too.
launch.py binds it (127.0.0.1 unless told otherwise) and runs it in a thread.

A page commands one robot (its namespace; the tools act there) and, when that robot is part of a fleet, also
draws every other robot of the fleet from an overview of each (`fleet` in the state message). Until the page
picks a robot itself, it follows the bridge's initial namespace (the first robot of a fleet once discovered).
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from starlette.applications import Starlette
from starlette.middleware import Middleware
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route, WebSocketRoute
from starlette.staticfiles import StaticFiles
from starlette.websockets import WebSocket, WebSocketDisconnect

from tb4.viewer.access import AccessMiddleware, AccessPolicy, policy_for
from tb4.viewer.protocol import (
    TOGGLE_LAYERS,
    Command,
    LayersCommand,
    NamespaceCommand,
    PoseCommand,
    ProtocolError,
    RateLimiter,
    parse_message,
)
from tb4.viewer.state import LAYERS, ClientCursor, ViewerState

__all__ = ["STATIC_DIR", "BridgeLike", "create_app", "UPDATE_RATE", "MAX_PAGES"]

STATIC_DIR = Path(__file__).resolve().parent / "static"
UPDATE_RATE = 10.0  # state messages per second to each page
MAX_PAGES = 16  # open pages at once; more are refused (each costs a little CPU per update)
SEND_TIMEOUT = 10.0  # s: a page that takes longer to accept one message is dropped
COMMAND_TIMEOUT = 10.0  # s for the ROS side to carry out one command


class BridgeLike(Protocol):
    """What the server needs from the ROS side (ViewerBridge; tests use a fake without DDS)."""

    default_namespace: str

    def acquire(self, namespace: str, timeout: float = ..., detailed: bool = ...) -> ViewerState: ...
    def release(self, namespace: str) -> None: ...
    def namespaces(self) -> list[str]: ...
    def initial_namespace(self) -> str: ...
    def command(self, namespace: str, command: Command) -> str: ...
    def close(self, timeout: float = ...) -> None: ...


def _finite(value: Any) -> Any:
    """Replace NaN/inf anywhere in a JSON-able value with None (the page's JSON parser rejects them)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(v) for v in value]
    return value


def _dumps(message: dict[str, Any]) -> str:
    try:
        return json.dumps(message, allow_nan=False, separators=(",", ":"))
    except ValueError:
        return json.dumps(_finite(message), allow_nan=False, separators=(",", ":"))


def _same_origin(websocket: WebSocket) -> bool:
    """Browsers send Origin on WebSockets; only our own page (same host:port) may drive the robot."""
    origin = websocket.headers.get("origin")
    if origin is None:
        return True  # not a browser (scripts, tests): nothing to protect against
    host = websocket.headers.get("host", "")
    return origin.split("://", 1)[-1].rstrip("/") == host


@dataclass
class _Member:
    """A fleet robot a page draws but does not command: its overview and what the page already has of it."""

    state: ViewerState
    cursor: ClientCursor = field(default_factory=ClientCursor)


@dataclass
class _Page:
    """One open page: the robot it commands, the fleet robots it draws, what it has, which optional layers."""

    websocket: WebSocket
    namespace: str
    state: ViewerState
    cursor: ClientCursor = field(default_factory=ClientCursor)
    layers: tuple[str, ...] = TOGGLE_LAYERS
    send_lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    limiter: RateLimiter = field(default_factory=RateLimiter)
    last_flood_notice: float = -math.inf
    picked: bool = False  # the page chose its robot; until then it follows the bridge's initial namespace
    members: dict[str, _Member] = field(default_factory=dict)
    robots_lock: asyncio.Lock = field(default_factory=asyncio.Lock)  # namespace and members change under it

    async def send(self, message: dict[str, Any]) -> None:
        async with self.send_lock:
            await asyncio.wait_for(self.websocket.send_text(_dumps(message)), SEND_TIMEOUT)


class _Viewer:
    """The app's behaviour; Starlette routes call into it."""

    def __init__(self, bridge: BridgeLike, update_rate: float) -> None:
        self.bridge = bridge
        self.period = 1.0 / update_rate
        self.pages = 0
        self.refused = 0

    async def index(self, _request: Request) -> Response:
        return FileResponse(STATIC_DIR / "index.html", headers={"Cache-Control": "no-cache"})

    async def health(self, _request: Request) -> Response:
        return JSONResponse(
            {
                "ok": bool(getattr(self.bridge, "alive", True)),
                "pages": self.pages,
                "refused": self.refused,
                "namespace": self.bridge.default_namespace,
                "namespaces": self.bridge.namespaces(),
            }
        )

    def _hello(self, page: _Page) -> dict[str, Any]:
        return {
            "type": "hello",
            "namespace": page.namespace,
            "namespaces": self.bridge.namespaces(),
            "update_rate": round(1.0 / self.period, 2),
            "layers": list(LAYERS),
        }

    async def websocket(self, websocket: WebSocket) -> None:
        if not _same_origin(websocket):
            await websocket.close(code=1008, reason="cross-origin WebSocket refused")
            return
        if self.pages >= MAX_PAGES:
            self.refused += 1
            await websocket.close(code=1013, reason=f"too many open pages (at most {MAX_PAGES})")
            return
        self.pages += 1
        namespace = self.bridge.initial_namespace()
        page: _Page | None = None
        try:
            await websocket.accept()
            state = await asyncio.to_thread(self.bridge.acquire, namespace)
            page = _Page(websocket, namespace, state)
            await page.send(self._hello(page))
            tasks = [asyncio.create_task(self._send_updates(page)), asyncio.create_task(self._receive_commands(page))]
            try:
                await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)  # a closed or stuck page ends both
            finally:
                for task in tasks:
                    task.cancel()
                for task in tasks:
                    with contextlib.suppress(asyncio.CancelledError, Exception):
                        await task
        except (WebSocketDisconnect, asyncio.TimeoutError, RuntimeError, OSError):
            pass  # the page went away (or stopped reading): its resources go below
        finally:
            self.pages -= 1
            if page is not None:
                self.bridge.release(page.namespace)
                for member in page.members:
                    self.bridge.release(member)

    async def _send_updates(self, page: _Page) -> None:
        loop = asyncio.get_running_loop()
        next_send = loop.time()
        while True:
            if not page.picked and (initial := self.bridge.initial_namespace()) != page.namespace:
                await self._switch_namespace(page, initial)  # e.g. the fleet's first robot, once discovered
            state = page.state  # may change when the page picks another namespace
            wanted = ("map", *page.layers)
            for name in state.layers_due(page.cursor, wanted):
                encoded = await asyncio.to_thread(state.layer_png, name)
                if encoded is None or page.state is not state:
                    continue
                version, grid, png = encoded
                await page.send(
                    {
                        "type": "layer",
                        "name": name,
                        "version": version,
                        "width": grid.width,
                        "height": grid.height,
                        "resolution": grid.resolution,
                        "origin": [grid.origin_x, grid.origin_y, grid.origin_yaw],
                        "frame": grid.frame,
                        "png": base64.b64encode(png).decode("ascii"),
                    }
                )
                page.cursor.layer_versions[name] = version
                page.cursor.layer_sent_at[name] = time.monotonic()
            fleet = await self._fleet_overview(page)
            if page.state is state:
                snapshot = state.snapshot(page.cursor)
                snapshot["namespaces"] = self.bridge.namespaces()
                snapshot["fleet"] = fleet
                await page.send(snapshot)
            next_send = max(next_send + self.period, loop.time())
            await asyncio.sleep(next_send - loop.time())

    async def _receive_commands(self, page: _Page) -> None:
        while True:
            message = await page.websocket.receive()
            if message["type"] == "websocket.disconnect":
                return
            text = message.get("text")
            payload = text if text is not None else (message.get("bytes") or b"")
            if not page.limiter.allow():
                now = time.monotonic()
                if now - page.last_flood_notice >= 1.0:  # one notice per second, not one per dropped message
                    page.last_flood_notice = now
                    await page.send(
                        {
                            "type": "error",
                            "message": f"too many messages: at most {page.limiter.rate:g} per second; "
                            f"{page.limiter.rejected} ignored so far",
                        }
                    )
                continue
            try:
                command = parse_message(payload)
            except ProtocolError as exc:
                await page.send({"type": "error", "message": f"rejected: {exc}"})
                continue
            await self._execute(page, command)

    async def _execute(self, page: _Page, command: Command) -> None:
        if isinstance(command, LayersCommand):
            page.layers = command.layers
            await page.send({"type": "ack", "command": "layers", "message": "layers: " + ", ".join(command.layers)})
            return
        if isinstance(command, NamespaceCommand):
            page.picked = True
            await self._switch_namespace(page, command.namespace)
            return
        try:
            text = await asyncio.wait_for(
                asyncio.to_thread(self.bridge.command, page.namespace, command), COMMAND_TIMEOUT
            )
        except (RuntimeError, ValueError, TimeoutError, asyncio.TimeoutError) as exc:
            await page.send({"type": "error", "message": f"{command.kind} failed: {exc or type(exc).__name__}"})
            return
        ack: dict[str, Any] = {"type": "ack", "command": command.kind, "message": text}
        if isinstance(command, PoseCommand):
            ack["pose"] = {"x": command.x, "y": command.y, "yaw": command.yaw}
        await page.send(ack)

    async def _switch_namespace(self, page: _Page, namespace: str) -> None:
        """Command another robot; the one left stays drawn (from its overview) if it is in the new one's fleet."""
        async with page.robots_lock:
            if namespace == page.namespace:
                await page.send(self._hello(page))
                return
            try:
                state = await asyncio.to_thread(self.bridge.acquire, namespace)
            except Exception as exc:
                await page.send({"type": "error", "message": f"cannot view namespace '{namespace or '/'}': {exc}"})
                return
            old, old_state = page.namespace, page.state
            page.namespace, page.state, page.cursor = namespace, state, ClientCursor()
            if old in state.fleet and old not in page.members:
                page.members[old] = _Member(old_state)  # its acquisition now holds the overview
            else:
                self.bridge.release(old)
            if page.members.pop(namespace, None) is not None:
                self.bridge.release(namespace)  # the commanded robot's own acquisition holds it now
            await page.send(self._hello(page))

    async def _fleet_overview(self, page: _Page) -> list[dict[str, Any]]:
        """The page's commanded robot's fleet, in order: an overview of every other robot (acquired while the page
        draws it), and a marker for the commanded one. Empty for a robot in no fleet."""
        async with page.robots_lock:
            fleet = page.state.fleet if page.namespace in page.state.fleet else ()
            for namespace in [ns for ns in page.members if ns not in fleet]:
                del page.members[namespace]
                self.bridge.release(namespace)
            for namespace in fleet:
                if namespace == page.namespace or namespace in page.members:
                    continue
                try:
                    state = await asyncio.to_thread(self.bridge.acquire, namespace, COMMAND_TIMEOUT, False)
                except Exception:  # noqa: BLE001 - the ROS side is busy or stopping: try again next update
                    continue
                state.join_fleet(fleet)  # drawn from its true pose even before its own fleet message arrives
                page.members[namespace] = _Member(state)
            return [
                {"namespace": ns, "picked": True}
                if ns == page.namespace
                else page.members[ns].state.overview(page.members[ns].cursor)
                for ns in fleet
                if ns == page.namespace or ns in page.members
            ]


def create_app(bridge: BridgeLike, update_rate: float = UPDATE_RATE, policy: AccessPolicy | None = None) -> Starlette:
    """The Starlette app: `/` the page, `/static` its files, `/ws` the live stream, `/api/health`.

    Args:
        bridge: the ROS side (ViewerBridge, or a fake in tests).
        update_rate: state messages per second to each page (0.1 to 60).
        policy: the Host names served and the token needed (default: loopback names only, no token).

    Returns:
        The app, with `app.state.viewer` (the pages).

    Raises:
        ValueError: an update rate out of range.
    """
    if not (0.1 <= update_rate <= 60.0):
        raise ValueError(f"update rate must be between 0.1 and 60 per second, got {update_rate}")
    viewer = _Viewer(bridge, update_rate)
    app = Starlette(
        routes=[
            Route("/", viewer.index),
            Route("/api/health", viewer.health),
            WebSocketRoute("/ws", viewer.websocket),
            Mount("/static", StaticFiles(directory=STATIC_DIR), name="static"),
        ],
        middleware=[Middleware(AccessMiddleware, policy=policy if policy is not None else policy_for("127.0.0.1", 0))],
    )
    app.state.viewer = viewer
    return app
