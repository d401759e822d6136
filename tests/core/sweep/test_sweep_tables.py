"""A sweep's matrix, its statistics and its files, without running a trial."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from tb4.sweep import ResultsTable, Row, Sweep, SweepError, SweepSpec, build_matrix, parse_seeds, wilson_interval
from tb4.sweep.results import percentile, reason_group
from tb4.sweep.runner import replay_command


def test_seeds_from_ranges_lists_and_mixes() -> None:
    assert parse_seeds("0:5") == [0, 1, 2, 3, 4]
    assert parse_seeds("7") == [7]
    assert parse_seeds("0:3,42,1") == [0, 1, 2, 42]


@pytest.mark.parametrize(
    ("text", "expected"),
    [("5:5", "is empty"), ("9:2", "is empty"), ("a:b", "must be N"), ("1,,2", "empty seed"), ("-3", "between 0")],
)
def test_bad_seeds_are_refused_with_the_reason(text: str, expected: str) -> None:
    with pytest.raises(ValueError, match=expected):
        parse_seeds(text)


def test_the_matrix_is_every_combination_with_seeds_innermost() -> None:
    trials = build_matrix([1, 2], ["warehouse", "depot"], [None, 0.5])
    assert len(trials) == 8 and [t.index for t in trials] == list(range(8))
    assert [(t.world, t.battery, t.seed) for t in trials[:3]] == [
        ("warehouse", None, 1),
        ("warehouse", None, 2),
        ("warehouse", 0.5, 1),
    ]
    assert len({t.key for t in trials}) == 8
    with pytest.raises(ValueError, match="battery must be between 0 and 1"):
        build_matrix([1], ["warehouse"], [1.5])
    with pytest.raises(ValueError, match="more than 1,000,000"):
        build_matrix(range(600_000), ["a", "b"])


def test_the_wilson_interval_is_honest_at_the_edges() -> None:
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)
    low, high = wilson_interval(10, 10)
    assert high == 1.0 and low == pytest.approx(0.7225, abs=1e-4)
    low, high = wilson_interval(50, 100)
    assert (low, high) == (pytest.approx(0.4038, abs=1e-4), pytest.approx(0.5962, abs=1e-4))
    assert wilson_interval(0, 0) == (0.0, 1.0)


def test_percentiles_and_reason_groups() -> None:
    assert percentile([3.0, 1.0, 2.0, 4.0], 50) == 2.5 and percentile([], 95) is None
    assert reason_group("stuck at (1.20, -3.40) after 12 s") == reason_group("stuck at (0.5, 2) after 7 s")


def _row(index: int, outcome: str, world: str = "warehouse", reason: str = "succeeded") -> Row:
    return Row(
        key=f"k{index}",
        index=index,
        seed=index,
        world=world,
        battery=None,
        exact=False,
        localization="amcl",
        outcome=outcome,
        reason=reason,
        sim_time=float(10 + index),
        wall_time=1.0,
        replay=f"tb4 run x --seed {index}",
    )


def test_summary_junit_and_csv(tmp_path: Path) -> None:
    table = ResultsTable(tmp_path)
    for k in range(8):
        table.add(_row(k, "succeeded"))
    table.add(_row(8, "failed", reason="goal 1 failed at (1.00, 2.00)"))
    table.add(_row(9, "failed", reason="goal 1 failed at (3.00, 4.50)"))
    table.add(_row(10, "errored", world="depot", reason="tb4 run refused it"))
    summary = table.summary()
    overall = summary["overall"]
    assert (overall["trials"], overall["succeeded"]) == (11, 8)
    warehouse = next(c for c in summary["cells"] if c["cell"]["world"] == "warehouse")
    assert warehouse["failures"] == [
        {"reason": "goal 1 failed at (1.00, 2.00)", "count": 2, "example": "tb4 run x --seed 8"}
    ]
    assert warehouse["sim_time_p50"] == 14.5
    root = ET.parse(table.write_junit(tmp_path / "junit.xml", "suite")).getroot()
    suite = root.find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("11", "2", "1")
    failure = root.find(".//failure")
    assert failure is not None and "replay: tb4 run x --seed 8" in (failure.text or "")
    assert len(table.write_csv().read_text().splitlines()) == 12
    again = ResultsTable.load(tmp_path)
    assert [r.key for r in again] == [r.key for r in table]


def test_a_row_cut_short_by_a_crash_is_skipped_on_resume(tmp_path: Path) -> None:
    table = ResultsTable(tmp_path)
    table.add(_row(0, "succeeded"))
    with table.jsonl.open("a") as stream:
        stream.write('{"key": "k1", "ind')  # killed mid-write
    assert [r.key for r in ResultsTable.load(tmp_path)] == ["k0"]


def test_a_folder_holding_another_sweep_or_unasked_results_is_refused(tmp_path: Path) -> None:
    spec = SweepSpec("nav_to_pose", build_matrix([0, 1], ["warehouse"]))
    sweep = Sweep(spec, tmp_path / "s")
    sweep.table.add(_row(0, "succeeded"))
    with pytest.raises(SweepError, match="holds this sweep's results already: --resume"):
        Sweep(spec, tmp_path / "s")
    resumed = Sweep(spec, tmp_path / "s", resume=True)
    assert len(resumed.pending) == 2  # the row's key is not one of this matrix's
    other = SweepSpec("nav_to_pose", build_matrix([0, 1, 2], ["warehouse"]))
    with pytest.raises(SweepError, match="holds another sweep"):
        Sweep(other, tmp_path / "s", resume=True)
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    with pytest.raises(SweepError, match="not empty and holds no sweep"):
        Sweep(spec, tmp_path / "busy")
    assert json.loads((tmp_path / "s" / "sweep.json").read_text())["identity"]["trials"] == 2


def test_the_replay_command_names_every_setting() -> None:
    trial = build_matrix([7], ["depot"], [0.25], (True,), ("truth",))[0]
    spec = SweepSpec("my mission.py", [trial], arguments=["--fast"], fail_on_bump=True)
    assert replay_command(spec, trial) == (
        "tb4 run 'my mission.py' --seed 7 --world depot --battery 0.25 --exact --localization truth "
        "--fail-on-bump -- --fast"
    )


def test_a_failure_run_folder_from_a_ray_node_is_written_here_with_its_replay_command(tmp_path: Path) -> None:
    from tb4.sweep.ray_backend import _localize, _run_files

    node_run = tmp_path / "node" / "000003-warehouse-s3"
    node_run.mkdir(parents=True)
    for name in ("run.json", "run.inputs.jsonl", "run.png", "mission.log"):
        (node_run / name).write_text(name)
    record = str(node_run / "run.json")
    row = Row(
        key="k", index=3, seed=3, world="warehouse", battery=None, exact=False, localization="amcl",
        outcome="failed", reason="exit code 3", exit_code=3, replay=f"tb4 replay {record}", run_dir=str(node_run),
        picture=str(node_run / "run.png"), record=record, node="n1",
    )  # fmt: skip
    files = _run_files(row)
    assert sorted(files) == ["mission.log", "run.inputs.jsonl", "run.json", "run.png"]
    here = _localize(tmp_path / "sweep", row, files)
    target = tmp_path / "sweep" / "runs" / "000003-n1"
    assert here.run_dir == str(target) and here.record == str(target / "run.json")
    assert here.picture == str(target / "run.png") and here.mcap == ""
    assert here.replay == f"tb4 replay {target / 'run.json'}"  # the journal beside it came too
    assert (target / "run.inputs.jsonl").read_text() == "run.inputs.jsonl"
    # a row whose folder was not kept keeps its `tb4 run` line
    plain = Row(key="k", index=1, seed=1, world="w", battery=None, exact=False, localization="amcl",
                outcome="errored", reason="x", replay="tb4 run m.py --seed 1")  # fmt: skip
    assert _localize(tmp_path / "sweep", plain, _run_files(plain)).replay == "tb4 run m.py --seed 1"


def test_a_sweeps_ray_actors_name_their_folders_after_it(tmp_path: Path) -> None:
    from tb4.sweep.ray_backend import node_folder_prefix

    assert node_folder_prefix(tmp_path / "a") == node_folder_prefix(tmp_path / "a")
    assert node_folder_prefix(tmp_path / "a") != node_folder_prefix(tmp_path / "b")
    assert node_folder_prefix(tmp_path / "a").startswith("tb4-sweep-ray-")


def test_workers_default_to_two_more_than_cores_only_when_trials_reuse_simulators(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from tb4.sweep.runner import default_workers

    monkeypatch.setattr("os.cpu_count", lambda: 2)
    trials = build_matrix([0, 1], ["warehouse"])
    assert default_workers(SweepSpec("nav_to_pose", trials)) == 4  # one simulator per worker, reset
    assert default_workers(SweepSpec("nav_to_pose", trials, reuse=False)) == 2  # --new-simulators
    assert default_workers(SweepSpec("nav_to_pose", trials, record=True)) == 2  # each trial a tb4 run
    assert default_workers(SweepSpec("fleet_delivery", trials)) == 2  # a fleet's world has no reset
    assert Sweep(SweepSpec("nav_to_pose", trials), tmp_path / "s").workers == 4
    assert Sweep(SweepSpec("nav_to_pose", trials), tmp_path / "t", workers=5).workers == 5
