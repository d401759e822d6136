"""Who may reach the viewer: the Host names it serves, and a per-launch token when it listens beyond loopback.

A browser enforces the same-origin rule by host *name*, not by address. A page on a domain whose DNS record is
switched to 127.0.0.1 after it loaded (DNS rebinding) is "same origin" with the viewer as far as the browser
knows: its requests carry `Host: evil.example:PORT` and a matching Origin. Checking Origin against Host alone
therefore lets it in. Refusing every Host name the viewer does not serve closes that door before any state is
sent or any command is read, for plain HTTP and WebSocket alike.

Beyond loopback the names that reach the machine cannot all be known (addresses, DNS names, a proxy), so there
the viewer also asks for a token made at launch, as notebook servers do: the URL it prints carries it once
(`?token=...`); the page's response sets it as a cookie for this port, so reloads and the page's WebSocket carry
it; scripts may pass it as the `token` query parameter.
"""

from __future__ import annotations

import hmac
import ipaddress
import secrets
import socket
from collections.abc import Awaitable, Callable, Iterable, MutableMapping
from dataclasses import dataclass, field
from typing import Any
from urllib.parse import parse_qs

__all__ = [
    "AccessPolicy",
    "AccessMiddleware",
    "LOOPBACK_NAMES",
    "TOKEN_PARAMETER",
    "host_name",
    "is_loopback",
    "is_wildcard",
    "policy_for",
]

Scope = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[MutableMapping[str, Any]]]
Send = Callable[[MutableMapping[str, Any]], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

LOOPBACK_NAMES = frozenset({"localhost", "127.0.0.1", "::1"})
WILDCARD_HOSTS = frozenset({"", "0.0.0.0", "::"})
TOKEN_PARAMETER = "token"


def is_loopback(host: str) -> bool:
    """True for a name or address that only this machine reaches (localhost, 127.0.0.0/8, ::1)."""
    name = host.strip("[]").lower().rstrip(".")
    if name == "localhost" or name.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def is_wildcard(host: str) -> bool:
    """True for a listening address that means "every interface" (0.0.0.0, ::)."""
    return host.strip("[]") in WILDCARD_HOSTS


def host_name(header: str) -> str:
    """The name part of a Host header (`name`, `name:port`, `[v6]:port`), lower case, without a trailing dot."""
    header = header.strip().lower()
    if header.startswith("["):
        name = header[1 : header.find("]")] if "]" in header else header[1:]
    elif header.count(":") == 1:
        name = header.split(":", 1)[0]
    else:
        name = header  # a bare IPv6 address (no port) or a name without a port
    return name.rstrip(".")


def _machine_names() -> set[str]:
    """This machine's own names and addresses: what a browser on the network types to reach a wildcard bind."""
    names: set[str] = set()
    for name in {socket.gethostname(), socket.getfqdn()}:
        if not name:
            continue
        names.add(name.lower())
        try:
            for info in socket.getaddrinfo(name, None):
                names.add(str(info[4][0]).lower())
        except OSError:
            pass  # a name that does not resolve still counts as itself
    return names


@dataclass(frozen=True)
class AccessPolicy:
    """The Host names the viewer answers to, and the token a request must carry (None: no token needed)."""

    hosts: frozenset[str]
    token: str | None = None
    port: int = 0
    cookie: str = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "cookie", f"tb4_viewer_token_{self.port}")

    def allows_host(self, header: str) -> bool:
        """Whether a Host header names this viewer (any loopback name always does)."""
        name = host_name(header)
        return name in self.hosts or is_loopback(name)

    def token_in(self, query_string: bytes, cookie_header: str) -> str | None:
        """The token a request carries in its query or its cookie, if any."""
        query = parse_qs(query_string.decode("latin-1"))
        if values := query.get(TOKEN_PARAMETER):
            return values[0]
        for part in cookie_header.split(";"):
            key, _, value = part.strip().partition("=")
            if key == self.cookie:
                return value
        return None

    def allows_token(self, offered: str | None) -> bool:
        """Whether the offered token is this launch's (always, when none is needed); constant-time."""
        if self.token is None:
            return True
        return offered is not None and hmac.compare_digest(offered.encode(), self.token.encode())


def policy_for(host: str, port: int, allow_hosts: Iterable[str] = (), token: bool | None = None) -> AccessPolicy:
    """The policy for a viewer listening on `host`.

    Args:
        host: the listening address or name (`--host`).
        port: the port actually bound (names the token's cookie).
        allow_hosts: more Host names to answer to (`--allow-host`: a proxy's name, a DNS alias).
        token: require a per-launch token; by default only when listening beyond loopback.

    Returns:
        The AccessPolicy: loopback names, `host` itself (or, for a wildcard bind, this machine's names and
        addresses), and `allow_hosts`.
    """
    hosts = set(LOOPBACK_NAMES)
    hosts.update(host_name(name) for name in allow_hosts if name.strip())
    if is_wildcard(host):
        hosts.update(_machine_names())
    else:
        hosts.add(host_name(host))
    needs_token = not is_loopback(host) if token is None else token
    return AccessPolicy(frozenset(hosts), secrets.token_urlsafe(24) if needs_token else None, port)


class AccessMiddleware:
    """ASGI middleware: a request whose Host the policy does not allow, or without its token, is refused before
    the app sees it (HTTP 403; a WebSocket is closed before it is accepted, which the server answers with 403).
    A page loaded with the right `?token=` gets it back as a cookie for later requests."""

    def __init__(self, app: ASGIApp, policy: AccessPolicy) -> None:
        self.app = app
        self.policy = policy

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = {key.decode("latin-1").lower(): value.decode("latin-1") for key, value in scope["headers"]}
        offered = self.policy.token_in(scope.get("query_string", b""), headers.get("cookie", ""))
        if not self.policy.allows_host(headers.get("host", "")):
            await self._refuse(scope, receive, send, f"host not served here: {headers.get('host', '')!r}")
            return
        if not self.policy.allows_token(offered):
            await self._refuse(scope, receive, send, "this viewer needs the token from the URL it printed")
            return
        if scope["type"] == "http" and self.policy.token is not None and offered is not None:
            send = self._setting_cookie(send)
        await self.app(scope, receive, send)

    def _setting_cookie(self, send: Send) -> Send:
        cookie = f"{self.policy.cookie}={self.policy.token}; Path=/; HttpOnly; SameSite=Strict"

        async def send_with_cookie(message: MutableMapping[str, Any]) -> None:
            if message["type"] == "http.response.start":
                message = dict(message)
                message["headers"] = [*message.get("headers", []), (b"set-cookie", cookie.encode("latin-1"))]
            await send(message)

        return send_with_cookie

    async def _refuse(self, scope: Scope, receive: Receive, send: Send, reason: str) -> None:
        if scope["type"] == "websocket":
            await receive()  # the connect event, which must come before a close
            await send({"type": "websocket.close", "code": 1008, "reason": reason[:120]})
            return
        body = (reason + "\n").encode("utf-8")
        await send(
            {
                "type": "http.response.start",
                "status": 403,
                "headers": [
                    (b"content-type", b"text/plain; charset=utf-8"),
                    (b"content-length", str(len(body)).encode()),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})
