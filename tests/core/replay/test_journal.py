"""The input journal and the replay engine without DDS: exact values, a core run replayed to the bit, a run that
does not depend on who reads the world, and journals that are malformed or hostile."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tb4.replay.core_world import CoreSettings, build_core_world
from tb4.replay.engine import ReplayError, replay
from tb4.replay.journal import InputJournal, JournalError, decode, encode, read_journal
from tb4.ros.loop import SimLoop
from tb4.sim.world import load_world


def test_values_come_back_equal_to_the_bit() -> None:
    values = [
        0.1 + 0.2,
        -0.0,
        5e-324,
        1.7976931348623157e308,
        math.pi,
        (1.0, (2.0, 3)),
        [(-13.0, 9.0, -1.5707963267948968)],
        {"cov": np.arange(9, dtype=np.float64).reshape(3, 3) / 7.0},
        np.float64(2.5),
        True,
        None,
        "a",
    ]
    for value in values:
        back = decode(json.loads(json.dumps(encode(value))))
        if isinstance(value, dict):
            assert np.array_equal(back["cov"], value["cov"]) and back["cov"].dtype == np.float64
        elif isinstance(value, float):
            assert math.copysign(1.0, back) == math.copysign(1.0, value) and back == value
        else:
            assert back == value and type(back) is type(value if not isinstance(value, np.generic) else 2.5)
    nan = decode(json.loads(json.dumps(encode(float("nan")))))
    assert math.isnan(nan)


def test_what_is_not_plain_data_is_no_input() -> None:
    with pytest.raises(TypeError, match="not a replayable input value"):
        encode(object())
    with pytest.raises(TypeError):
        encode({"__tuple__": 1})


def _live_run(
    tmp_path: Path,
    exact: bool,
    reader: Callable[[SimLoop], None] | None = None,
    ticks: int = 700,
    late: int = 0,
) -> Path:
    """A run as the simulator's loop serves it, its inputs applied between ticks as requests are; `reader` runs
    after every tick as a publisher would; `late` ticks delay the navigation goal."""
    world = load_world("warehouse")
    settings = CoreSettings(seed=7, exact=exact)
    core = build_core_world(world, settings)
    loop = SimLoop(core.sims[0], core.navs[0], rate=math.inf)
    loop.journal = InputJournal(
        {"world": "warehouse", "world_file": str(world.source), "control_period": 0.05, **settings.to_json()}
    )
    inputs = loop.inputs
    script: dict[int, Callable[[], None]] = {
        3: lambda: inputs.nav.set_initial_pose(0.0, 0.0, 0.0),
        5: lambda: inputs.sim.start_undock(),
        6: lambda: loop.call_outside_replay(lambda: None, "a light ring", moves=False),
        200 + late: lambda: tasks.append(inputs.nav.start_navigate_to_pose((-3.0, 2.0, 1.0))),
        420: lambda: inputs.cancel(tasks[-1]),
        430: lambda: inputs.sim.set_velocity_command(0.1, 0.5),
        460: lambda: inputs.nav.start_spin(1.2, 10.0, False),
        520: lambda: inputs.nav.clear_local(),
    }
    tasks: list[object] = []
    for tick in range(1, ticks + 1):
        if tick in script:
            loop.submit(script[tick])
        loop.tick(fast_forward=False)
        if reader is not None:
            reader(loop)
    path = tmp_path / f"run-{exact}-{late}-{reader is not None}.inputs.jsonl"
    return loop.journal.write(path)


def test_a_core_run_replays_bit_for_bit(tmp_path: Path) -> None:
    path = _live_run(tmp_path, exact=False)
    journal = read_journal(path)
    assert [i.name for i in journal.inputs] == [
        "nav.set_initial_pose",
        "sim.start_undock",
        "nav.start_navigate_to_pose",
        "task 1.cancel",  # the undock is task 0: tasks are numbered in start order
        "sim.set_velocity_command",
        "nav.start_spin",
        "nav.clear_local",
    ]
    report = replay(path)
    assert report.identical and report.divergence is None, report.summary()
    assert report.left_out == ("a light ring",) and report.untracked == () and report.reproducible
    assert report.final_poses == journal.end.poses and report.ticks == 700
    assert math.hypot(*report.final_poses[0][:2]) > 0.5  # the robot went somewhere


def test_a_run_is_the_same_whoever_reads_the_world(tmp_path: Path) -> None:
    """Publishers, viewers and service calls read scans and costmaps at their own pace: that must not change the
    run (it did: the lidar's noise stream advanced with each reader, and reading a costmap updated it)."""

    def publisher(loop: SimLoop) -> None:
        loop.sim.scan()
        loop.nav.current_local_costmap()
        loop.nav.planning_costmap()

    quiet = read_journal(_live_run(tmp_path, exact=False))
    busy = read_journal(_live_run(tmp_path, exact=False, reader=publisher))
    assert quiet.end.digest == busy.end.digest


def test_a_goal_two_seconds_late_is_another_run_and_replay_says_where(tmp_path: Path) -> None:
    on_time = read_journal(_live_run(tmp_path, exact=True))
    late_path = _live_run(tmp_path, exact=True, late=40)
    assert read_journal(late_path).end.digest != on_time.end.digest
    # the late run's journal with the goal moved back to its on-time tick: replay must notice the change
    lines = late_path.read_text().splitlines()
    for k, line in enumerate(lines):
        data = json.loads(line)
        if data.get("call") == "nav.start_navigate_to_pose":
            data["tick"] = 200
            lines[k] = json.dumps(data)
    late_path.write_text("\n".join(lines) + "\n")
    report = replay(late_path)
    assert not report.identical and report.divergence is not None
    assert report.divergence.tick == 220  # the first checkpoint after the goal's tick
    assert "first differs at tick 220" in report.summary()


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("not json", "not JSON"),
        ('{"tick": 1, "robot": 0, "call": "sim.step"}', "'sim.step' is not a replayable input"),
        ('{"tick": 1, "robot": 0, "call": "nav.__init__"}', "not a replayable input"),
        ('{"tick": 1, "robot": 0, "call": "os.system", "args": ["true"]}', "not a replayable input"),
        ('{"tick": -1, "robot": 0, "call": "nav.clear_local"}', "whole numbers"),
        ('{"tick": 1, "robot": 0, "call": "task.cancel"}', "needs a task number"),
        (
            '{"tick": 1, "robot": 0, "call": "nav.set_initial_pose", "args": '
            '[{"__array__": "float64", "shape": [1000000], "data": [1]}]}',
            "does not hold",
        ),
        ('{"tick": 1, "robot": 0, "call": "nav.clear_local", "args": [{"__array__": "object"}]}', "malformed array"),
        ("[1, 2]", "JSON object"),
    ],
)
def test_a_malformed_journal_line_is_named(tmp_path: Path, line: str, message: str) -> None:
    path = tmp_path / "bad.inputs.jsonl"
    header = json.dumps({"tb4_journal": 1, "settings": {"world": "warehouse"}})
    end = json.dumps({"end": {"ticks": 1, "digest": "x"}})
    path.write_text("\n".join([header, line, end]) + "\n")
    with pytest.raises(JournalError, match=message) as err:
        read_journal(path)
    assert f"{path}:2" in str(err.value)


def test_journals_that_are_not_whole(tmp_path: Path) -> None:
    path = tmp_path / "x.inputs.jsonl"
    path.write_bytes(b"\xff\xfe")
    with pytest.raises(JournalError, match="not text"):
        read_journal(path)
    path.write_text(json.dumps({"tb4_journal": 1, "settings": {}}) + "\n")
    with pytest.raises(JournalError, match="no end line"):
        read_journal(path)
    path.write_text("")
    with pytest.raises(JournalError, match="empty"):
        read_journal(path)
    header = json.dumps({"tb4_journal": 1, "settings": {}})
    path.write_text(header + "\n" + json.dumps({"end": {"ticks": 10**12, "digest": "x"}}) + "\n")
    with pytest.raises(JournalError, match="a journal holds 0 to"):  # a replay would step for days
        read_journal(path)
    with pytest.raises(ReplayError, match="no such run folder"):
        replay(tmp_path / "missing")
    with pytest.raises(ReplayError, match="not a run folder"):
        replay(tmp_path)
    (tmp_path / "run.json").write_text(json.dumps({"summary": {}}))
    with pytest.raises(ReplayError, match="no input journal"):
        replay(tmp_path)


def test_a_journal_for_a_world_it_does_not_fit(tmp_path: Path) -> None:
    path = tmp_path / "run.inputs.jsonl"
    lines = [
        json.dumps({"tb4_journal": 1, "settings": {"world": "warehouse", "seed": 1}}),
        json.dumps({"tick": 1, "robot": 3, "call": "nav.clear_local"}),
        json.dumps({"end": {"ticks": 2, "digest": "x"}}),
    ]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReplayError, match="robot 3, but the world has 1"):
        replay(path)
    lines[0] = json.dumps({"tb4_journal": 1, "settings": {"world": "no_such_world"}})
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReplayError, match="cannot be loaded"):
        replay(path)
