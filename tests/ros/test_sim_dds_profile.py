"""The simulator's DDS participant announces itself every 0.5 s and its reliable writers send heartbeats every 0.1 s,
and under Fast DDS 3 it propagates no types (tb4.rosenv.apply_simulator_dds_profile): each Fast DDS (3 for Kilted,
2 for Jazzy, which reads another variable and names the heartbeat period otherwise) loads its profile without a
parse error, and a profile file the user chose is left in place. Under loopback discovery our processes, the
simulator included, take their DDS data over UDP on 127.0.0.1, not over shared memory (tb4.rosenv.
apply_loopback_dds_profile): no process of a run maps a Fast DDS port segment. Runs in both stages: the files differ
by middleware. That the heartbeats come that often is tests/ros/test_action_feedback.py's: a goal's second feedback
waits for them."""

from __future__ import annotations

import os
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from irobot_create_msgs.msg import DockStatus

from tb4.processes import ros_environment, tb4_command
from tb4.rosenv import (
    FASTDDS_PROFILE_VARIABLES,
    LOOPBACK_DDS_PROFILE,
    SIMULATOR_DDS_PROFILE,
    SIMULATOR_DDS_PROFILE_FAST_DDS_2,
    SIMULATOR_LOOPBACK_DDS_PROFILE,
    SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2,
    apply_safe_ros_defaults,
    apply_simulator_dds_profile,
    installed_middleware,
    simulator_dds_profile,
)

NS = {"d": "http://www.eprosima.com"}


def _period(root: ET.Element, element: str) -> float:
    found = root.find(f".//d:{element}", NS)
    assert found is not None, element
    return int(found.find("d:sec", NS).text) + int(found.find("d:nanosec", NS).text) / 1e9  # type: ignore[union-attr,arg-type]


@pytest.mark.parametrize(
    ("profile", "heartbeat"),
    [
        (SIMULATOR_DDS_PROFILE, "heartbeat_period"),
        (SIMULATOR_LOOPBACK_DDS_PROFILE, "heartbeat_period"),
        (SIMULATOR_DDS_PROFILE_FAST_DDS_2, "heartbeatPeriod"),
        (SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2, "heartbeatPeriod"),
    ],
)
def test_the_profiles_say_half_a_second_and_a_tenth(profile: Path, heartbeat: str) -> None:
    root = ET.parse(profile).getroot()
    assert _period(root, "leaseAnnouncement") == 0.5
    assert _period(root, heartbeat) == 0.1


def test_fast_dds_3_propagates_no_types() -> None:
    """Fast DDS 3 holds back a remote endpoint until it knows its type, and can wait for good (bench_discovery);
    without type information in the simulator's announcements nobody waits. Fast DDS 2 has no such wait."""
    for profile in (SIMULATOR_DDS_PROFILE, SIMULATOR_LOOPBACK_DDS_PROFILE):
        properties = {
            p.findtext("d:name", namespaces=NS): p.findtext("d:value", namespaces=NS)
            for p in ET.parse(profile).getroot().iterfind(".//d:property", NS)
        }
        assert properties == {"fastdds.type_propagation": "disabled"}, profile
    for profile in (SIMULATOR_DDS_PROFILE_FAST_DDS_2, SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2, LOOPBACK_DDS_PROFILE):
        assert ET.parse(profile).getroot().find(".//d:property", NS) is None, profile


def _data_locators(profile: Path) -> list[tuple[str, str | None]]:
    listed = ET.parse(profile).getroot().find(".//d:defaultUnicastLocatorList", NS)
    return (
        []
        if listed is None
        else [
            (kind.tag.split("}")[1], kind.findtext("d:address", namespaces=NS))
            for kind in listed.iterfind("d:locator/*", NS)
        ]
    )


@pytest.mark.parametrize(
    "profile", [LOOPBACK_DDS_PROFILE, SIMULATOR_LOOPBACK_DDS_PROFILE, SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2]
)
def test_loopback_profiles_take_data_over_udp_on_127_0_0_1_only(profile: Path) -> None:
    assert _data_locators(profile) == [("udpv4", "127.0.0.1")]


@pytest.mark.parametrize("profile", [SIMULATOR_DDS_PROFILE, SIMULATOR_DDS_PROFILE_FAST_DDS_2])
def test_beyond_this_machine_the_simulator_leaves_fast_dds_its_locators(profile: Path) -> None:
    assert _data_locators(profile) == []


@pytest.mark.parametrize(
    ("fast_dds", "variable", "profile", "loopback_profile"),
    [
        ("3.2.3", "FASTDDS_DEFAULT_PROFILES_FILE", SIMULATOR_DDS_PROFILE, SIMULATOR_LOOPBACK_DDS_PROFILE),
        (
            "2.14.5",
            "FASTRTPS_DEFAULT_PROFILES_FILE",
            SIMULATOR_DDS_PROFILE_FAST_DDS_2,
            SIMULATOR_LOOPBACK_DDS_PROFILE_FAST_DDS_2,
        ),
    ],
)
def test_only_without_a_profile_of_the_users_and_only_for_fast_dds(
    fast_dds: str, variable: str, profile: Path, loopback_profile: Path
) -> None:
    env: dict[str, str] = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    apply_simulator_dds_profile(env, fast_dds)
    assert env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET", variable: str(profile)}
    for loopback in ({"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}, {"ROS_LOCALHOST_ONLY": "1"}):
        env = dict(loopback)
        apply_simulator_dds_profile(env, fast_dds)
        assert env == {**loopback, variable: str(loopback_profile)}
    for name in FASTDDS_PROFILE_VARIABLES:
        # the loopback profile a tb4 command set for its children, whichever Fast DDS it had, gives way
        env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", name: str(LOOPBACK_DDS_PROFILE)}
        apply_simulator_dds_profile(env, fast_dds)
        assert env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", variable: str(loopback_profile)}
        env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", name: "/home/me/mine.xml"}
        apply_simulator_dds_profile(env, fast_dds)
        assert env == {"ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", name: "/home/me/mine.xml"}
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    apply_simulator_dds_profile(env, fast_dds)
    assert env == {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}


@pytest.mark.parametrize(
    ("fast_dds", "variable", "other"),
    [
        ("3.2.3", "FASTDDS_DEFAULT_PROFILES_FILE", "FASTRTPS_DEFAULT_PROFILES_FILE"),
        ("2.14.5", "FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE"),
    ],
)
def test_every_process_of_ours_takes_the_loopback_profile_under_loopback_discovery_only(
    fast_dds: str, variable: str, other: str
) -> None:
    env: dict[str, str] = {}
    apply_safe_ros_defaults(env, fast_dds)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env[variable] == str(LOOPBACK_DDS_PROFILE) and other not in env
    env = {"ROS_LOCALHOST_ONLY": "1"}
    apply_safe_ros_defaults(env, fast_dds)
    assert env[variable] == str(LOOPBACK_DDS_PROFILE)
    # set by a process of the other distribution, from this install or another one: replaced by ours
    for theirs in (LOOPBACK_DDS_PROFILE, Path("/opt/jazzy/lib/python3.12/site-packages/tb4/ros/fastdds_loopback.xml")):
        env = {other: str(theirs)}
        apply_safe_ros_defaults(env, fast_dds)
        assert env[variable] == str(LOOPBACK_DDS_PROFILE) and other not in env
    env = {"ROS_AUTOMATIC_DISCOVERY_RANGE": "localhost"}  # rcl: not a range it knows, so localhost (and a warning)
    apply_safe_ros_defaults(env, fast_dds)
    assert env[variable] == str(LOOPBACK_DDS_PROFILE)
    for chosen in (
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "SYSTEM_DEFAULT"},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "OFF"},
        {"ROS_AUTOMATIC_DISCOVERY_RANGE": "", "ROS_LOCALHOST_ONLY": "0"},
        {"ROS_LOCALHOST_ONLY": "0"},
    ):
        env = dict(chosen)  # a real robot's network: Fast DDS's own locators, shared memory and all
        apply_safe_ros_defaults(env, fast_dds)
        assert not any(name in env for name in FASTDDS_PROFILE_VARIABLES), env
    env = {other: "/home/me/mine.xml"}
    apply_safe_ros_defaults(env, fast_dds)
    assert env[other] == "/home/me/mine.xml" and variable not in env
    env = {other: ""}  # set empty by the user: theirs, left as it is (Fast DDS reports it cannot read it)
    apply_safe_ros_defaults(env, fast_dds)
    assert env[other] == "" and variable not in env
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    apply_safe_ros_defaults(env, fast_dds)
    assert not any(name in env for name in FASTDDS_PROFILE_VARIABLES), env


def test_the_simulator_sets_the_profile_before_its_first_node(monkeypatch) -> None:
    from tb4.cli import cmd_sim
    from tb4.cli.main import main

    for name in FASTDDS_PROFILE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    variable, profile = simulator_dds_profile(installed_middleware().fast_dds, loopback=True)
    seen: list[str | None] = []

    class Stop(Exception):
        pass

    def require_ros() -> None:  # the first thing after the profile: no node exists yet
        seen.append(os.environ.get(variable))
        raise Stop

    monkeypatch.setattr(cmd_sim, "require_ros", require_ros)
    with pytest.raises(Stop):
        main(["sim"])
    assert seen == [str(profile)]


def test_fast_dds_parses_our_profile_and_the_users_own_file_wins(start_simulator, start_process, ros, tmp_path) -> None:
    variable, profile = simulator_dds_profile(installed_middleware().fast_dds, loopback=True)
    sim = start_simulator("--rate", "1")
    assert "XMLPARSER" not in sim.output(), sim.output()  # Fast DDS reports a profile it cannot parse
    assert "Invalid value for property" not in sim.output(), sim.output()  # ... and a property it does not know
    assert ros.wait_for(ros.latest(DockStatus, "dock_status"), timeout=30.0, what="dock_status").is_docked
    sim.stop()
    mine = tmp_path / "mine.xml"  # a user's file, broken on purpose: Fast DDS must be reading it, not ours
    mine.write_text(profile.read_text().replace("<sec>0</sec>", "<sec>zero</sec>"))
    env = {**ros_environment(int(os.environ["ROS_DOMAIN_ID"])), variable: str(mine)}
    other = start_process(tb4_command("sim", "--rate", "1"), name="sim-mine", env=env)
    assert other.wait_for_output("XMLPARSER", 60), other.output()


def _port_segments(pid: int) -> set[str]:
    """The Fast DDS shared-memory port segments process `pid` has mapped: the ones it listens on and the ones of the
    processes it sends to that way (Fast DDS 3 names them fastdds_port<N>, Fast DDS 2 fastrtps_port<N>)."""
    with open(f"/proc/{pid}/maps") as maps:
        return {line.split()[-1] for line in maps if re.search(r"/dev/shm/fast(dds|rtps)_port\d+$", line.strip())}


USER_SCRIPT = """
import os, sys, time
import tb4.navigator  # what a user's mission imports first
import rclpy
from irobot_create_msgs.msg import DockStatus

rclpy.init()
node = rclpy.create_node("a_users_script")
seen = []
node.create_subscription(DockStatus, "dock_status", seen.append, 10)
deadline = time.monotonic() + 60
while not seen and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
with open(f"/proc/{os.getpid()}/maps") as maps:
    ports = sorted({line.split()[-1] for line in maps if "_port" in line and "/dev/shm/" in line})
print("dock_status:", bool(seen), "ports:", ports, flush=True)
time.sleep(30)  # keeps the script alive while the test reads the simulator's mappings
"""


def test_no_process_of_ours_takes_dds_data_over_shared_memory(start_simulator, start_process, ros, ros_env, tmp_path):
    """Shared memory under a busy machine can lose one direction of a pair of processes' data for good
    (ros/fastdds_loopback.xml): the simulator, a user's script and this test's own node carry theirs over loopback
    UDP, and still reach each other."""
    sim = start_simulator("--rate", "1")
    assert ros.wait_for(ros.latest(DockStatus, "dock_status"), timeout=30.0, what="dock_status").is_docked
    script = tmp_path / "mission.py"
    script.write_text(USER_SCRIPT)
    env = {name: value for name, value in ros_env.items() if name not in FASTDDS_PROFILE_VARIABLES}
    user = start_process([sys.executable, str(script)], name="user-script", env=env, cwd=tmp_path)
    assert user.wait_for_output("dock_status:", 60), user.output()
    assert "dock_status: True ports: []" in user.output(), user.output()
    assert _port_segments(sim.pid) == set()
    assert _port_segments(os.getpid()) == set()
