"""The pairs users have across ROS 2 distributions, over real DDS: a process on ROS 2 Jazzy's own middleware (rclpy 7,
Fast DDS 2.14) with one on Kilted's (rclpy 9, Fast DDS 3.2), both speaking Nav2 Jazzy's nav2_msgs, as a TurtleBot 4
on Jazzy does. Every type hash is the same on both sides (checked first), so this is the pairing that is meaningful:
a Kilted environment with Kilted's nav2_msgs differs from Jazzy in nine nav2_msgs actions (NavigateThroughPoses,
FollowWaypoints, Spin, BackUp...).

Each direction shares one simulator: a navigator on Jazzy drives `tb4 sim` on Kilted's middleware, and a navigator on
Kilted's middleware drives `tb4 sim` on Jazzy, through Nav2's actions (navigate to pose, through poses, waypoints)
and the Create 3's (undock, dock); then a TurtleBot 4 tutorial (`tb4 run ... --attach`) runs across the same pair.
make test runs this stage with the Jazzy environment's pytest (here) and the Jazzy wire environment as the peer
(TB4_CROSS_PEER_VENV, tests/cross/conftest.py)."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")

from tb4.processes import READY_LINE, ManagedProcess, remove_stale_shm, shm_snapshot  # noqa: E402

from .conftest import PROGRAMS, Side, own_environment  # noqa: E402

DRIVE_STEPS = ["undock", "navigate_to_pose", "navigate_through_poses", "follow_waypoints", "dock"]


def _run(side: Side, args: list[str], domain_id: int, timeout: float) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        args,
        env=own_environment(domain_id),
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


def _doctor(side: Side, domain_id: int) -> str:
    done = _run(side, side.tb4("doctor"), domain_id, timeout=60)
    assert done.returncode == 0, (side.name, done.stdout, done.stderr)
    return done.stdout


def _simulator(side: Side, domain_id: int, logs: Path) -> Iterator[ManagedProcess]:
    before = shm_snapshot()
    sim = ManagedProcess(
        side.tb4("sim", "--rate", "max", "--hold"), env=own_environment(domain_id), log_path=logs / "sim.log"
    )
    try:
        assert sim.wait_for_output(READY_LINE, 90), f"{side.name}: simulator did not start:\n{sim.output()}"
        yield sim
    finally:
        sim.stop()
        remove_stale_shm(before)


def _drive(navigator: Side, sim: ManagedProcess, domain_id: int) -> None:
    done = _run(navigator, navigator.command(str(PROGRAMS / "drive.py")), domain_id, timeout=300)
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    steps = {line["step"]: line["result"] for line in lines if "step" in line}
    report = f"{navigator.name}: exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert lines and lines[0]["wire_format"] == "jazzy", report
    assert [s for s in steps if s in DRIVE_STEPS] == DRIVE_STEPS, report
    assert all(result == "succeeded" for result in steps.values()), report
    assert done.returncode == 0, report
    assert sim.alive(), sim.output()[-3000:]


def _tutorial(navigator: Side, name: str, sim: ManagedProcess, domain_id: int, out: Path) -> None:
    done = _run(
        navigator,
        navigator.tb4("run", name, "--attach", "--json", "--output-dir", str(out)),
        domain_id,
        timeout=300,
    )
    events = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    report = f"{navigator.name}: tb4 run {name}: exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    assert done.returncode == 0 and events and events[-1]["event"] == "end", report
    assert events[-1]["exit_code"] == 0, report
    assert any(e.get("event") == "log" and "Goal succeeded!" in e.get("line", "") for e in events), report
    assert sim.alive(), sim.output()[-3000:]


# Class-scoped: each direction's simulator lives while its class runs, so the two never share a domain (without
# pytest-xdist, one worker runs both classes one after the other).
@pytest.fixture(scope="class")
def sim_on_kilted(peer: Side, ros_domain_id: int, tmp_path_factory: pytest.TempPathFactory) -> Iterator[ManagedProcess]:
    """`tb4 sim` on the peer, Kilted's middleware with Jazzy's nav2_msgs."""
    yield from _simulator(peer, ros_domain_id, tmp_path_factory.mktemp("sim_on_kilted"))


@pytest.fixture(scope="class")
def sim_on_jazzy(here: Side, ros_domain_id: int, tmp_path_factory: pytest.TempPathFactory) -> Iterator[ManagedProcess]:
    """`tb4 sim` here, on ROS 2 Jazzy's own middleware."""
    yield from _simulator(here, ros_domain_id, tmp_path_factory.mktemp("sim_on_jazzy"))


def test_both_sides_speak_jazzys_wire_format_on_two_middlewares(here: Side, peer: Side, ros_domain_id: int) -> None:
    """The pair is what it claims: Jazzy's middleware here, Kilted's there, Jazzy's nav2_msgs on both, and every
    type hash of the interface packages the same on both sides (what DDS endpoints of the two announce)."""
    ours, theirs = _doctor(here, ros_domain_id), _doctor(peer, ros_domain_id)
    assert "ROS 2 Jazzy (rclpy 7." in ours and "Fast DDS 2.14" in ours, ours
    assert "ROS 2 Kilted (rclpy 9." in theirs and "Fast DDS 3." in theirs, theirs
    for report in (ours, theirs):
        assert "nav2_msgs wire format        jazzy" in report, report
    hashes = []
    for side in (here, peer):
        done = _run(side, side.command(str(PROGRAMS / "type_hashes.py")), ros_domain_id, timeout=60)
        assert done.returncode == 0, (side.name, done.stderr)
        hashes.append(json.loads(done.stdout))
    assert "nav2_msgs/action/NavigateThroughPoses" in hashes[0], sorted(hashes[0])[:20]
    names = hashes[0].keys() | hashes[1].keys()
    differing = sorted(name for name in names if hashes[0].get(name) != hashes[1].get(name))
    assert differing == [], differing


class TestJazzyNavigatorDrivesASimulatorOnKiltedMiddleware:
    """A navigator on ROS 2 Jazzy (a user's Jazzy install, or the TurtleBot 4's own) and `tb4 sim` on Kilted's
    middleware serving Jazzy's nav2_msgs (what `TB4_ROS_DISTRO=jazzy` on a Kilted base gives)."""

    pytestmark = pytest.mark.xdist_group("cross_jazzy_navigator")

    def test_nav2_and_create3_actions(self, here: Side, sim_on_kilted: ManagedProcess, ros_domain_id: int) -> None:
        _drive(here, sim_on_kilted, ros_domain_id)

    def test_a_tutorial(self, here: Side, sim_on_kilted: ManagedProcess, ros_domain_id: int, tmp_path: Path) -> None:
        _tutorial(here, "nav_through_poses", sim_on_kilted, ros_domain_id, tmp_path)


class TestKiltedNavigatorDrivesASimulatorOnJazzy:
    """A navigator on Kilted's middleware with Jazzy's nav2_msgs (this project's environment on a user's computer)
    and `tb4 sim` on ROS 2 Jazzy's own middleware, as a TurtleBot 4 on Jazzy serves Nav2 and the Create 3."""

    pytestmark = pytest.mark.xdist_group("cross_kilted_navigator")

    def test_nav2_and_create3_actions(self, peer: Side, sim_on_jazzy: ManagedProcess, ros_domain_id: int) -> None:
        _drive(peer, sim_on_jazzy, ros_domain_id)

    def test_a_tutorial(self, peer: Side, sim_on_jazzy: ManagedProcess, ros_domain_id: int, tmp_path: Path) -> None:
        _tutorial(peer, "nav_to_pose", sim_on_jazzy, ros_domain_id, tmp_path)
