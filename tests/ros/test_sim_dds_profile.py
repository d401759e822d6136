"""The simulator's DDS participant announces itself every 0.5 s and its reliable writers send heartbeats every 0.1 s,
and under Fast DDS 3 it propagates no types (tb4.rosenv.apply_simulator_dds_profile): each Fast DDS (3 for Kilted,
2 for Jazzy, which reads another variable and names the heartbeat period otherwise) loads its profile without a
parse error, and a profile file the user chose is left in place. Runs in both stages: the file differs by
middleware. That the heartbeats come that often is tests/ros/test_action_feedback.py's: a goal's second feedback
waits for them."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from irobot_create_msgs.msg import DockStatus

from tb4.processes import ros_environment, tb4_command
from tb4.rosenv import (
    FASTDDS_PROFILE_VARIABLES,
    SIMULATOR_DDS_PROFILE,
    SIMULATOR_DDS_PROFILE_FAST_DDS_2,
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
    [(SIMULATOR_DDS_PROFILE, "heartbeat_period"), (SIMULATOR_DDS_PROFILE_FAST_DDS_2, "heartbeatPeriod")],
)
def test_the_profiles_say_half_a_second_and_a_tenth(profile: Path, heartbeat: str) -> None:
    root = ET.parse(profile).getroot()
    assert _period(root, "leaseAnnouncement") == 0.5
    assert _period(root, heartbeat) == 0.1


def test_fast_dds_3_propagates_no_types() -> None:
    """Fast DDS 3 holds back a remote endpoint until it knows its type, and can wait for good (bench_discovery);
    without type information in the simulator's announcements nobody waits. Fast DDS 2 has no such wait."""
    properties = {
        p.findtext("d:name", namespaces=NS): p.findtext("d:value", namespaces=NS)
        for p in ET.parse(SIMULATOR_DDS_PROFILE).getroot().iterfind(".//d:property", NS)
    }
    assert properties == {"fastdds.type_propagation": "disabled"}
    assert ET.parse(SIMULATOR_DDS_PROFILE_FAST_DDS_2).getroot().find(".//d:property", NS) is None


@pytest.mark.parametrize(
    ("fast_dds", "variable", "profile"),
    [
        ("3.2.3", "FASTDDS_DEFAULT_PROFILES_FILE", SIMULATOR_DDS_PROFILE),
        ("2.14.5", "FASTRTPS_DEFAULT_PROFILES_FILE", SIMULATOR_DDS_PROFILE_FAST_DDS_2),
    ],
)
def test_only_without_a_profile_of_the_users_and_only_for_fast_dds(fast_dds: str, variable: str, profile: Path) -> None:
    env: dict[str, str] = {}
    apply_simulator_dds_profile(env, fast_dds)
    assert env == {variable: str(profile)}
    for name in FASTDDS_PROFILE_VARIABLES:
        env = {name: "/home/me/mine.xml"}
        apply_simulator_dds_profile(env, fast_dds)
        assert env == {name: "/home/me/mine.xml"}
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    apply_simulator_dds_profile(env, fast_dds)
    assert env == {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}


def test_the_simulator_sets_the_profile_before_its_first_node(monkeypatch) -> None:
    from tb4.cli import cmd_sim
    from tb4.cli.main import main

    for name in FASTDDS_PROFILE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    variable, profile = simulator_dds_profile(installed_middleware().fast_dds)
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
    variable, profile = simulator_dds_profile(installed_middleware().fast_dds)
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
