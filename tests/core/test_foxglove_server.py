"""FoxgloveLive's server without DDS: where it listens, what it says when it cannot, what a connecting client is
offered, who gets in (the SDK checks neither Host nor Origin: the reason it stays on loopback), how a channel's
messages are paced and latched ones sent again, and how messages that come before the first /clock wait for it."""

from __future__ import annotations

import json
import socket
import struct
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("foxglove", reason="the [foxglove] extra is not installed")
websockets_sync = pytest.importorskip("websockets.sync.client", reason="the test client needs websockets")

from tb4.foxglove import FoxgloveError  # noqa: E402
from tb4.foxglove.live import (  # noqa: E402
    CLOCK_WARN,
    HEAVY_TYPES,
    PERIOD,
    RESEND_PERIOD,
    FoxgloveLive,
    _clock_nanoseconds,
    _Topic,
)

pytestmark = pytest.mark.core


@pytest.fixture
def live() -> Iterator[FoxgloveLive]:
    server = FoxgloveLive("127.0.0.1", 0, report=lambda text: None)
    yield server
    server.close()


def _server_info(url: str, **headers: Any) -> dict[str, Any]:
    with websockets_sync.connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=10, **headers) as ws:
        return dict(json.loads(ws.recv(timeout=10)))


def test_port_zero_takes_a_free_loopback_port_and_says_where(live: FoxgloveLive) -> None:
    assert live.port > 0 and live.url == f"ws://127.0.0.1:{live.port}"
    assert live.app_url is not None and f"127.0.0.1%3A{live.port}" in live.app_url


def test_a_client_is_offered_sim_time_and_nothing_to_command_with(live: FoxgloveLive) -> None:
    info = _server_info(live.url)
    assert info["op"] == "serverInfo" and info["capabilities"] == ["time"]
    wall = FoxgloveLive("127.0.0.1", 0, sim_time=False)
    try:
        assert _server_info(wall.url)["capabilities"] == []
    finally:
        wall.close()


def test_a_port_in_use_is_said_with_what_to_do() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        with pytest.raises(FoxgloveError) as failed:
            FoxgloveLive("127.0.0.1", port)
    assert str(failed.value) == (
        f"port {port} on 127.0.0.1 is in use (another Foxglove server, the viewer or `tb4 sim`?): give another one "
        "with --foxglove PORT, or 0 for any free port"
    )


def test_an_address_that_does_not_resolve_is_said_as_such() -> None:
    with pytest.raises(FoxgloveError, match="cannot listen on 'no-such-host.invalid': no such address"):
        FoxgloveLive("no-such-host.invalid", 0)


def test_the_sdk_checks_neither_host_nor_origin_so_the_server_stays_on_loopback(live: FoxgloveLive) -> None:
    """What a DNS-rebound or cross-site page would send is served: the SDK has no hook to refuse it (the viewer's
    tb4.viewer.access cannot be applied), which is why --foxglove binds 127.0.0.1 and a wider address needs
    --foxglove-allow-remote. If a later SDK refuses these, the docs' limitation can go."""
    info = _server_info(
        live.url, origin="http://evil.example", additional_headers={"Host": f"evil.example:{live.port}"}
    )
    assert info["op"] == "serverInfo"


def test_loopback_is_all_the_default_server_listens_on(live: FoxgloveLive) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("192.0.2.1", 9))  # a documentation address: no packet is sent, the route picks our address
            address = probe.getsockname()[0]
        except OSError:
            pytest.skip("this machine has no route off loopback")
    if address.startswith("127."):
        pytest.skip("this machine has no address beyond loopback")
    with pytest.raises(OSError), socket.create_connection((address, live.port), timeout=2):
        pass


# --- pacing and latching, on a channel of our own (no DDS) ----------------------------------------------------------
class _Channel:
    def __init__(self) -> None:
        self.logged: list[tuple[bytes, int | None]] = []

    def log(self, data: bytes, log_time: int | None = None) -> None:
        self.logged.append((data, log_time))

    def topic(self) -> str:
        return "/test"

    def close(self) -> None:
        pass


def _topic(
    live: FoxgloveLive, period: float, latched: bool = False, keep: int = 1, clock: bool = True
) -> tuple[_Topic, _Channel]:
    """A topic served by `live`, on a channel of our own; `clock`: a first /clock has come (sim time)."""
    if clock:
        live._clock_ns = 1_000_000_000
    channel = _Channel()
    topic = _Topic("test", "/test", None, None, latched=latched, keep=keep, period=period)
    topic.channels.append((channel, None))
    live._topics.append(topic)
    live._by_channel[7] = topic
    return topic, channel


def test_a_fast_topic_sends_the_newest_message_once_its_period_ends(live: FoxgloveLive) -> None:
    topic, channel = _topic(live, period=HEAVY_TYPES["nav_msgs/msg/OccupancyGrid"])
    for data in (b"first", b"second", b"third"):
        live._received(topic, data)
    assert [data for data, _ in channel.logged] == [b"first"]  # the others came within the period
    assert live._due(time.monotonic()) == []
    due = live._due(time.monotonic() + topic.period)
    assert due == [(topic, b"third")]  # the newest, not a backlog
    assert live._due(time.monotonic() + 10 * topic.period) == []


def test_messages_are_logged_at_the_latest_clock_time(live: FoxgloveLive) -> None:
    topic, channel = _topic(live, period=PERIOD)
    live._clock_ns = 12_500_000_000
    live._received(topic, b"data")
    assert channel.logged == [(b"data", 12_500_000_000)]


def _clock_cdr(nanoseconds: int) -> bytes:
    """A serialized rosgraph_msgs/Clock (little-endian CDR)."""
    return b"\x00\x01\x00\x00" + struct.pack("<iI", *divmod(nanoseconds, 1_000_000_000))


def test_messages_before_the_first_clock_wait_for_it_and_are_logged_at_its_time(live: FoxgloveLive) -> None:
    """The simulator sends /clock only once it has matched our reader, which a loaded machine makes seconds late;
    the odometry that came before was logged at time zero, seconds of sim time before its own stamp."""
    odom, odom_channel = _topic(live, period=PERIOD, clock=False)
    grid, grid_channel = _topic(live, period=0.0, latched=True, keep=2, clock=False)
    for data in (b"odom 1", b"odom 2"):
        live._received(odom, data)
    for data in (b"map", b"costmap"):
        live._received(grid, data)
    assert odom_channel.logged == [] and grid_channel.logged == []
    now = time.monotonic()
    assert live._due(now + 10.0) == []  # nothing is due before the first clock, however long it takes
    assert live._next_wake() > 0.5  # and the worker does not spin meanwhile
    live._tick(_clock_cdr(3_250_000_000))
    due = live._due(time.monotonic())
    assert due == [(odom, b"odom 2"), (grid, b"map"), (grid, b"costmap")]  # the newest; every latched one kept
    for served, data in due:
        live._send(served, data)
    assert odom_channel.logged == [(b"odom 2", 3_250_000_000)]
    assert grid_channel.logged == [(b"map", 3_250_000_000), (b"costmap", 3_250_000_000)]
    live._received(odom, b"odom 3")  # from now on paced as before
    assert live._due(time.monotonic() + odom.period) == [(odom, b"odom 3")]


def test_a_clock_that_never_comes_is_named_once_its_wait_is_long(live: FoxgloveLive) -> None:
    now = time.monotonic()
    assert not live._clock_late(now)  # /clock not subscribed yet: nothing is late
    live._clock_subscribed = now - CLOCK_WARN + 1.0
    assert not live._clock_late(now)
    assert live._clock_late(now + 1.0)
    live._tick(_clock_cdr(50_000_000))
    assert not live._clock_late(now + 1.0)


def test_without_sim_time_nothing_waits_for_a_clock() -> None:
    wall = FoxgloveLive("127.0.0.1", 0, sim_time=False, report=lambda text: None)
    try:
        topic, channel = _topic(wall, period=PERIOD, clock=False)
        before = time.time_ns()
        wall._received(topic, b"data")
        assert len(channel.logged) == 1 and channel.logged[0][1] >= before
    finally:
        wall.close()


def test_a_latched_topic_is_sent_again_to_a_client_that_subscribes_later(live: FoxgloveLive) -> None:
    topic, channel = _topic(live, period=0.0, latched=True, keep=2)
    for data in (b"laser", b"laser", b"camera", b"wheels"):  # one writer's transform each; a repeat is kept once
        live._received(topic, data)
    assert list(topic.kept) == [b"camera", b"wheels"]
    topic.subscription = object()  # fed over DDS already: a new client gets nothing from DDS again
    live._subscribed(7, +1)
    now = time.monotonic()
    assert live._due(now + RESEND_PERIOD) == [(topic, b"camera"), (topic, b"wheels")]
    live._subscribed(7, +1)  # a flood of subscriptions: one re-send per RESEND_PERIOD
    live._subscribed(7, +1)
    assert live._due(now + RESEND_PERIOD + 0.01) == []
    assert len(live._due(now + 2 * RESEND_PERIOD + 0.01)) == 2
    live._subscribed(7, -1)
    live._subscribed(7, -1)
    live._subscribed(7, -1)
    live._subscribed(7, -1)  # more than it had: the count stays at zero
    assert topic.wanted == 0


def test_the_clock_is_read_from_its_cdr_bytes() -> None:
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock

    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = 4242, 5
    assert _clock_nanoseconds(serialize_message(clock)) == 4242 * 1_000_000_000 + 5
    assert _clock_nanoseconds(b"\x00\x01") is None
    assert _clock_nanoseconds(b"\x00\x03\x00\x00" + bytes(8)) is None
