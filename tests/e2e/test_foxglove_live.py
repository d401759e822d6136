"""`tb4 sim --foxglove`, checked with a real WebSocket client speaking the Foxglove protocol as the app does
(tests/e2e/foxglove_client.py): the channels and their ROS 2 schemas, messages decoded with rclpy as the simulator
sent them, a client that comes late, clients that misbehave, a port in use (`tb4 run --foxglove`:
test_foxglove_run.py)."""

from __future__ import annotations

import math
import re
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
pytest.importorskip("foxglove", reason="the [foxglove] extra is not installed")
pytest.importorskip("websockets", reason="the test client needs websockets (the [viewer] extra)")

from websockets.exceptions import ConnectionClosed  # noqa: E402

from tb4.processes import READY_LINE, ManagedProcess, remove_stale_shm, shm_snapshot, tb4_command  # noqa: E402
from tb4.runner.mcap_record import message_definition  # noqa: E402
from tb4.sim.world import load_world  # noqa: E402

from .foxglove_client import FoxgloveClient  # noqa: E402
from .tutorial_runs import environment  # noqa: E402

# one module-scoped simulator serves the tests that share it: pytest-xdist keeps them on one worker (--dist loadgroup)
pytestmark = pytest.mark.xdist_group("foxglove_live")

SERVED = {
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/global_costmap/costmap": "nav_msgs/msg/OccupancyGrid",
    "/local_costmap/costmap": "nav_msgs/msg/OccupancyGrid",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/plan": "nav_msgs/msg/Path",
    "/particle_cloud": "nav2_msgs/msg/ParticleCloud",
    "/particle_cloud/poses": "geometry_msgs/msg/PoseArray",
    "/goals": "nav_msgs/msg/Goals",
    "/goals/poses": "geometry_msgs/msg/PoseArray",
    "/amcl_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/battery_state": "sensor_msgs/msg/BatteryState",
    "/dock_status": "irobot_create_msgs/msg/DockStatus",
    "/clock": "rosgraph_msgs/msg/Clock",
}
URL = re.compile(r"tb4 foxglove: (ws://127\.0\.0\.1:\d+)")


class Served:
    def __init__(self, sim: ManagedProcess, url: str) -> None:
        self.sim, self.url = sim, url

    def client(self) -> FoxgloveClient:
        return FoxgloveClient(self.url)


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    """`tb4 sim --foxglove 0` (any free port; the URL it prints says which), at real time."""
    logs = tmp_path_factory.mktemp("foxglove_live")
    before = shm_snapshot()
    sim = ManagedProcess(
        tb4_command("sim", "--world", "warehouse", "--foxglove", "0"), env=environment(), log_path=logs / "sim.log"
    )
    try:
        assert sim.wait_for_output(READY_LINE, 90), sim.output()
        match = URL.search(sim.output())
        assert match, sim.output()
        yield Served(sim, match.group(1))
    finally:
        sim.stop()
        remove_stale_shm(before)


def test_every_topic_is_advertised_with_its_full_ros2msg_schema(served: Served) -> None:
    with served.client() as client:
        channels = client.wait_for_channels(SERVED)
        for topic, type_name in SERVED.items():
            channel = channels[topic]
            assert (channel["encoding"], channel["schemaEncoding"], channel["schemaName"]) == (
                "cdr",
                "ros2msg",
                type_name,
            ), topic
            assert channel["schema"] == message_definition(type_name), topic
        # read only: nothing a client could publish, call or set is offered (sim time is announced)
        assert client.server_info["capabilities"] == ["time"], client.server_info


def test_the_map_odom_scan_and_clock_decode_as_the_simulator_sent_them(served: Served) -> None:
    world_map = load_world("warehouse").map
    with served.client() as client:
        client.wait_for_channels(SERVED)
        client.subscribe(["/map", "/odom", "/scan", "/tf_static", "/clock", "/global_costmap/costmap"])
        _, _, grid = client.next_message(["/map"])
        assert grid.header.frame_id == "map"
        assert (grid.info.height, grid.info.width) == world_map.data.shape
        assert grid.info.resolution == pytest.approx(world_map.resolution)
        assert len(grid.data) == grid.info.width * grid.info.height
        _, _, costmap = client.next_message(["/global_costmap/costmap"])
        assert costmap.header.frame_id == "map"  # the global costmap covers the map, at its own resolution
        for cells, map_cells in ((costmap.info.width, grid.info.width), (costmap.info.height, grid.info.height)):
            assert abs(cells * costmap.info.resolution - map_cells * grid.info.resolution) <= costmap.info.resolution
        _, _, odom = client.next_message(["/odom"])
        assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
        # docked, and odometry starts where the robot starts: at the odom frame's origin
        assert math.hypot(odom.pose.pose.position.x, odom.pose.pose.position.y) < 0.05
        _, _, scan = client.next_message(["/scan"])
        assert scan.header.frame_id == "rplidar_link" and len(scan.ranges) > 100
        _, _, static = client.next_message(["/tf_static"])
        assert ("base_link", "rplidar_link") in {(t.header.frame_id, t.child_frame_id) for t in static.transforms}
        # sim time: a message goes out at the latest /clock time, so a clock message's own time is its log time
        _, log_time, clock = client.next_message(["/clock"])
        assert log_time == clock.clock.sec * 1_000_000_000 + clock.clock.nanosec
        _, odom_time, later = client.next_message(["/odom"])
        stamp = later.header.stamp.sec * 1_000_000_000 + later.header.stamp.nanosec
        assert abs(odom_time - stamp) < 500_000_000  # within half a second of sim time


def test_a_client_that_comes_later_still_gets_the_latched_map(served: Served) -> None:
    """The SDK keeps no message for a late subscriber; the map, published once, is sent again when one comes."""
    with served.client() as first:
        first.wait_for_channels(["/map"])
        first.subscribe(["/map", "/tf_static"])
        first.next_message(["/map"])
        with served.client() as second:
            second.wait_for_channels(["/map", "/tf_static"])
            second.subscribe(["/map", "/tf_static"])
            second.next_message(["/map"], timeout=10)
            second.next_message(["/tf_static"], timeout=10)


def test_misbehaving_clients_get_an_answer_and_the_simulator_keeps_serving(served: Served) -> None:
    host, port = served.url.removeprefix("ws://").rsplit(":", 1)
    # connect and drop: at the TCP level, halfway through a handshake, and as a client that got its channels
    for _ in range(10):
        with socket.create_connection((host, int(port)), timeout=5):
            pass
    with socket.create_connection((host, int(port)), timeout=5) as half:
        half.sendall(b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\n")
    for _ in range(10):
        with served.client() as dropped:
            dropped.wait_for_channels(["/odom"])
            dropped.subscribe(["/odom", "/map"])
    # unknown channel ids and frames that are not the protocol: each gets a status error
    with served.client() as client:
        client.wait_for_channels(["/odom"])
        client.send({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 987654}]})
        status = client.wait_for_status(lambda s: "987654" in s["message"])
        assert status["level"] == 2, status  # an error
        for junk in ("not json", '{"op": "no such op"}', b"\x07binary junk", '{"op": "advertise", "channels": []}'):
            client.send(junk)
        client.count(1.0)
    # a flood, bounded in count and time: subscriptions flipped as fast as the socket takes them, and a reader that
    # subscribes to everything (the map and the costmaps too) and never reads
    flooder = FoxgloveClient(served.url, close_timeout=1.0)  # neither reads: neither waits for a goodbye
    lazy = FoxgloveClient(served.url, close_timeout=1.0)
    try:
        flooder.wait_for_channels(["/odom", "/map"])
        lazy.wait_for_channels(SERVED)
        lazy.subscribe(SERVED)
        odom, grid = flooder.channels["/odom"]["id"], flooder.channels["/map"]["id"]
        sent, started = 0, time.monotonic()
        while sent < 3000 and time.monotonic() - started < 5.0:
            ids = [sent + 1, sent + 2]
            flooder.send(
                {
                    "op": "subscribe",
                    "subscriptions": [{"id": ids[0], "channelId": odom}, {"id": ids[1], "channelId": grid}],
                }
            )
            flooder.send({"op": "unsubscribe", "subscriptionIds": ids})
            sent += 2
        assert sent >= 100, sent
        time.sleep(2.0)
    except ConnectionClosed:
        pass  # the server may drop a client that floods it: that is an answer too
    finally:
        flooder.close()
        lazy.close()
    # still serving: a new client gets the latched map and live odometry, and the simulator runs on
    with served.client() as fresh:
        fresh.wait_for_channels(["/map", "/odom"])
        fresh.subscribe(["/map", "/odom"])
        fresh.next_message(["/map"], timeout=15)
        fresh.next_message(["/odom"], timeout=15)
    assert served.sim.alive(), served.sim.output()
    assert "Traceback" not in served.sim.output(), served.sim.output()


def test_a_port_in_use_stops_tb4_sim_before_it_starts(busy_port: int, tmp_path: Path) -> None:
    before = shm_snapshot()
    sim = ManagedProcess(
        tb4_command("sim", "--foxglove", str(busy_port)), env=environment(), log_path=tmp_path / "sim.log"
    )
    try:
        code = sim.popen.wait(timeout=60)
    finally:
        sim.stop()
        remove_stale_shm(before)
    output = sim.output()
    assert code == 2, output
    assert f"port {busy_port} on 127.0.0.1 is in use" in output and "--foxglove PORT" in output, output
    assert READY_LINE not in output and "route graph" not in output, output  # nothing of the simulator was built


def test_a_foxglove_host_beyond_loopback_is_refused_unless_allowed(tmp_path: Path) -> None:
    proc = ManagedProcess(
        tb4_command("sim", "--foxglove", "--foxglove-host", "0.0.0.0"), env=environment(), log_path=tmp_path / "s.log"
    )
    try:
        code = proc.popen.wait(timeout=60)
    finally:
        proc.stop()
    assert code == 2, proc.output()
    assert "--foxglove-allow-remote" in proc.output() and READY_LINE not in proc.output(), proc.output()
