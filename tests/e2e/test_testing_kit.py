"""The test kit as a user meets it: the pytest plugin's fixtures in this suite, and a user's own test folder run by
pytest under -n 2, with assertions that name the picture when they fail."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tb4.testing import (
    RunRecord,
    assert_clearance,
    assert_finished_within,
    assert_no_collision,
    assert_reached,
    assert_succeeded,
    assert_visited_in_order,
)

from .test_own_missions import MISSION


@pytest.mark.tb4(world="warehouse", seed=3)
def test_a_script_as_a_trial_gives_its_record(tb4_mission, tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(MISSION)
    record = tb4_mission(tmp_path / "mission.py", "--exit", "0")
    assert isinstance(record, RunRecord) and record.seed == 3
    assert_succeeded(record)
    assert_visited_in_order(record, [(2.0, 1.0)])
    assert_no_collision(record)
    assert assert_clearance(record, at_least=0.05) < 5.0
    assert_finished_within(record, 300)
    assert record.battery[:, 1].min() > 0.9 and record.battery[-1, 0] > 0  # sampled once per sim second
    assert record.picture is not None and record.picture.is_file()
    assert record.replay().identical  # the run again, to the bit, from its journal


def test_a_callable_as_a_trial(tb4_trial) -> None:
    def mission(navigator) -> None:
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startToPose(navigator.getPoseStamped([1.5, -1.0], 0))

    record = tb4_trial(mission, seed=1, localization="truth")
    assert_succeeded(record)
    assert_reached(record, (1.5, -1.0))
    assert record.data["run"]["mission"]["kind"] == "callable"

    def broken(navigator) -> None:
        raise ValueError("no such shelf")

    failed = tb4_trial(broken)
    assert not failed.succeeded and failed.reason == "ValueError: no such shelf"


def test_a_failed_assertion_names_the_picture_and_where_the_robot_was(tb4_mission, tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(MISSION)
    record = tb4_mission(tmp_path / "mission.py", "--exit", "3", exact=True)
    with pytest.raises(AssertionError) as failed:
        assert_succeeded(record)
    assert "exit code 3" in str(failed.value) and f"picture {record.picture}" in str(failed.value)
    assert f"replay: tb4 replay {record.path}" in str(failed.value)
    with pytest.raises(AssertionError, match=r"never reached \(9, 9\) within 0.4 m: closest \d+\.\d\d m at t="):
        assert_reached(record, (9.0, 9.0))


@pytest.mark.tb4(world="depot", localization="truth")
def test_the_navigator_fixture_drives_the_tests_own_simulator(tb4_navigator, tb4_simulator) -> None:
    tb4_navigator.waitUntilNav2Active()
    tb4_navigator.undock()
    record = tb4_simulator.finish()
    assert [e["action"] for e in record.goals] == ["undock"] and not record.docked_at_end
    assert record.data["world"] == "depot"


def test_an_unknown_setting_says_what_was_meant() -> None:
    from tb4.testing.plugin import settings_from

    with pytest.raises(TypeError, match="unknown simulator setting 'sed'; did you mean 'seed'"):
        settings_from(sed=3)


USER_TESTS = textwrap.dedent(
    """\
    import pytest
    from tb4.testing import assert_docked_at_end, assert_succeeded, assert_visited_in_order


    @pytest.mark.tb4(seed=3)
    def test_my_mission(tb4_mission):
        record = tb4_mission("mission.py")
        assert_succeeded(record)
        assert_visited_in_order(record, [(2.0, 1.0)])


    @pytest.mark.tb4(seed=4)
    def test_my_mission_another_seed(tb4_mission):
        assert_succeeded(tb4_mission("mission.py"))


    def test_it_ends_docked(tb4_mission):
        assert_docked_at_end(tb4_mission("mission.py"))
    """
)


def test_a_users_own_tests_run_under_xdist_and_leave_nothing_behind(tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(MISSION)
    (tmp_path / "test_mission.py").write_text(USER_TESTS)
    installed = any(ep.name == "tb4" for ep in importlib.metadata.entry_points(group="pytest11"))
    plugin = [] if installed else ["-p", "tb4.testing.plugin"]  # an editable install made before the entry point
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "TB4_TEST"))}
    basetemp = tmp_path / "user-tmp"  # every run folder and simulator record of the user's tests is under it
    pytest_command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider"]
    proc = subprocess.run(
        [*pytest_command, *plugin, "-n", "2", "-q", "--basetemp", str(basetemp), "test_mission.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert "1 failed, 2 passed" in proc.stdout, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "AssertionError: not docked at the end at (" in proc.stdout and "run.png; replay: tb4 replay " in proc.stdout
    leftovers = subprocess.run(["pgrep", "-f", str(basetemp)], capture_output=True, text=True)
    assert leftovers.stdout == ""  # no simulator, tb4 run or mission process of theirs is left
