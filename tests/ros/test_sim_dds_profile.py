"""The simulator's DDS participant announces itself every 0.5 s (tb4.rosenv.apply_simulator_dds_profile): Fast DDS
loads our profile without a parse error, and a profile file the user chose is left in place."""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET

import pytest
from irobot_create_msgs.msg import DockStatus

from tb4.processes import ros_environment, tb4_command
from tb4.rosenv import FASTDDS_PROFILE_VARIABLES, SIMULATOR_DDS_PROFILE, apply_simulator_dds_profile


def test_the_profile_says_half_a_second() -> None:
    ns = {"d": "http://www.eprosima.com"}
    period = ET.parse(SIMULATOR_DDS_PROFILE).getroot().find(".//d:leaseAnnouncement", ns)
    assert period is not None
    assert int(period.find("d:sec", ns).text) == 0  # type: ignore[union-attr]
    assert int(period.find("d:nanosec", ns).text) == 500_000_000  # type: ignore[union-attr]


def test_only_without_a_profile_of_the_users_and_only_for_fast_dds() -> None:
    env: dict[str, str] = {}
    apply_simulator_dds_profile(env)
    assert env == {"FASTDDS_DEFAULT_PROFILES_FILE": str(SIMULATOR_DDS_PROFILE)}
    for name in FASTDDS_PROFILE_VARIABLES:
        env = {name: "/home/me/mine.xml"}
        apply_simulator_dds_profile(env)
        assert env == {name: "/home/me/mine.xml"}
    env = {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}
    apply_simulator_dds_profile(env)
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in env


def test_the_simulator_sets_the_profile_before_its_first_node(monkeypatch) -> None:
    from tb4.cli import cmd_sim
    from tb4.cli.main import main

    for name in FASTDDS_PROFILE_VARIABLES:
        monkeypatch.delenv(name, raising=False)
    seen: list[str | None] = []

    class Stop(Exception):
        pass

    def require_ros() -> None:  # the first thing after the profile: no node exists yet
        seen.append(os.environ.get("FASTDDS_DEFAULT_PROFILES_FILE"))
        raise Stop

    monkeypatch.setattr(cmd_sim, "require_ros", require_ros)
    with pytest.raises(Stop):
        main(["sim"])
    assert seen == [str(SIMULATOR_DDS_PROFILE)]


def test_fast_dds_parses_our_profile_and_the_users_own_file_wins(start_simulator, start_process, ros, tmp_path) -> None:
    sim = start_simulator("--rate", "1")
    assert "XMLPARSER" not in sim.output(), sim.output()  # Fast DDS reports a profile it cannot parse
    assert ros.wait_for(ros.latest(DockStatus, "dock_status"), timeout=30.0, what="dock_status").is_docked
    sim.stop()
    mine = tmp_path / "mine.xml"  # a user's file, broken on purpose: Fast DDS must be reading it, not ours
    mine.write_text(SIMULATOR_DDS_PROFILE.read_text().replace("<sec>0</sec>", "<sec>zero</sec>"))
    env = {**ros_environment(int(os.environ["ROS_DOMAIN_ID"])), "FASTDDS_DEFAULT_PROFILES_FILE": str(mine)}
    other = start_process(tb4_command("sim", "--rate", "1"), name="sim-mine", env=env)
    assert other.wait_for_output("XMLPARSER", 60), other.output()
