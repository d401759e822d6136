"""`tb4 sweep` as a user runs it: a matrix with a failing cell, its table, summary, JUnit and failure folders;
Ctrl-C and --resume; what it refuses; and the same trials on a real local Ray cluster."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import tempfile
import textwrap
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import pytest

from tb4.core.waits import wait_until

from .tutorial_runs import TB4, environment

# Fails in the depot, succeeds in the warehouse: a mission whose outcome the matrix decides. It drives nothing, so
# a trial is the simulator's start and stop; the sweep's machinery is what is under test.
WORLD_MISSION = textwrap.dedent(
    """\
    import os, sys, time
    world = os.environ.get("TB4_WORLD")
    time.sleep(float(os.environ.get("MISSION_SLEEP", "0")))
    if world == "depot":
        print("[ERROR] [mission]: no shelves in the depot", flush=True)
        sys.exit(3)
    """
)


def _sweep(args: list[str], cwd: Path, timeout: float = 300, env: dict[str, str] | None = None):
    return subprocess.run(
        [*TB4, "sweep", *args],
        cwd=cwd,
        env=env or environment(),
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


def _rows(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "results.jsonl").read_text().splitlines()]


def test_a_sweep_writes_rows_summary_junit_and_keeps_its_failures(tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    out = tmp_path / "sweep"
    proc = _sweep(
        ["mission.py", "--seeds", "0:2", "--world", "warehouse,depot", "--output", str(out), "--junit", "j.xml"],
        tmp_path,
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr  # some trials failed
    rows = sorted(_rows(out), key=lambda r: r["index"])
    assert [(r["world"], r["seed"], r["outcome"]) for r in rows] == [
        ("warehouse", 0, "succeeded"),
        ("warehouse", 1, "succeeded"),
        ("depot", 0, "failed"),
        ("depot", 1, "failed"),
    ]
    failed = rows[2]
    assert failed["exit_code"] == 3 and "no shelves in the depot" in failed["reason"]
    assert Path(failed["picture"]).is_file() and Path(failed["record"]).is_file()
    assert failed["replay"] == f"tb4 replay {failed['record']}"  # the failed run itself, from its journal
    assert rows[0]["run_dir"] == "" and not any((out / "runs").glob("000000-*"))  # successes leave only a row
    summary = json.loads((out / "summary.json").read_text())
    depot = next(c for c in summary["cells"] if c["cell"]["world"] == "depot")
    assert depot["succeeded"] == 0 and depot["wilson95"][0] == 0.0 and depot["failures"][0]["count"] == 2
    assert "world depot, battery -, exact False, amcl: 0/2 succeeded" in proc.stdout
    assert len((out / "results.csv").read_text().splitlines()) == 5
    suite = ET.parse(tmp_path / "j.xml").getroot().find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("failures")) == ("4", "2")
    # each failure's replay command re-runs the very trial, to the bit (one of them ran on a reset simulator)
    for row in rows[2:]:
        _assert_replays(row)
        # its record ends where its trial did: not rewritten with the idle ticks before its simulator was closed
        record = json.loads(Path(row["record"]).read_text())
        assert abs(record["summary"]["sim_time"] - row["sim_time"]) < 0.5, (record["summary"], row)


def _assert_replays(row: dict) -> None:
    """The row's replay command re-runs its trial here, to the bit."""
    replay = subprocess.run(
        [*TB4, *row["replay"].split()[1:]],
        env=environment(),
        capture_output=True,
        text=True,
        timeout=120,
        stdin=subprocess.DEVNULL,
    )
    assert replay.returncode == 0 and "bit for bit" in replay.stdout, replay.stdout + replay.stderr


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["mission.py", "--seeds", "5:5"], "is empty"),
        (["mission.py", "--seeds", "0:2", "--world", "warehose"], "did you mean 'warehouse'"),
        (["mission.py", "--seeds", "0:2", "--battery", "2"], "battery must be between 0 and 1"),
        (["mission.py", "--seeds", "0:2", "--localization", "gps"], "'gps' is not amcl, truth or odometry"),
        (["nosuch.py", "--seeds", "0:2"], "no such file"),
        (["mission.py", "--seeds", "0:2", "--output", "busy"], "not empty and holds no sweep"),
    ],
)
def test_what_a_sweep_refuses_before_any_trial(tmp_path: Path, args: list[str], expected: str) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "notes.txt").write_text("mine")
    proc = _sweep(args, tmp_path, timeout=60)
    assert proc.returncode == 2 and expected in proc.stderr, proc.stdout + proc.stderr


def _interrupt_after_a_row(args: list[str], cwd: Path, env: dict[str, str], out: Path) -> tuple[int, str, float]:
    """Start a sweep, Ctrl-C it once it has kept a row: its exit code, its output, the seconds it took to end."""
    proc = subprocess.Popen(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 180
        while not (out / "results.jsonl").is_file() or not _rows(out):
            assert time.monotonic() < deadline and proc.poll() is None, "no row within 180 s"
            time.sleep(0.1)
        started = time.monotonic()
        proc.send_signal(signal.SIGINT)
        stdout, _ = proc.communicate(timeout=90)
        return proc.returncode, stdout, time.monotonic() - started
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)


def test_ctrl_c_keeps_finished_rows_ends_every_trial_and_resume_goes_on(tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    out = tmp_path / "sweep"
    env = {**environment(), "MISSION_SLEEP": "1.5"}
    args = [*TB4, "sweep", "mission.py", "--seeds", "0:8", "--workers", "2", "--output", str(out), "--json"]
    code, stdout, seconds = _interrupt_after_a_row(args, tmp_path, env, out)
    assert code == 130 and seconds < 30
    kept = _rows(out)
    assert 1 <= len(kept) < 8 and json.loads(stdout.splitlines()[-1])["canceled"] is True
    leftovers = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True)
    assert leftovers.stdout == ""  # no tb4 run, simulator or mission of the sweep is left
    forks = subprocess.run(["pgrep", "-f", str(tmp_path / "mission.py")], capture_output=True, text=True)
    assert forks.stdout == ""  # nor a fork server of its missions, nor a mission forked and waiting
    again = _sweep(["mission.py", "--seeds", "0:8", "--output", str(out), "--resume"], tmp_path)
    assert again.returncode == 0, again.stdout + again.stderr
    rows = _rows(out)
    assert sorted(r["seed"] for r in rows) == list(range(8))  # each trial once: the kept ones were not run again
    assert f"{len(kept)} already done" in again.stdout


# Hangs the first time it runs (a marker file says it has), then ends at once.
HANG_ONCE_MISSION = textwrap.dedent(
    """\
    import os, time
    marker = os.path.join(os.path.dirname(os.path.abspath(__file__)), "hung")
    if not os.path.exists(marker):
        open(marker, "w").close()
        print("hanging", flush=True)
        time.sleep(600)
    """
)


def test_a_hung_trial_is_ended_at_its_time_limit_and_the_worker_goes_on_with_the_same_simulator(
    tmp_path: Path,
) -> None:
    (tmp_path / "mission.py").write_text(HANG_ONCE_MISSION)
    out = tmp_path / "sweep"
    proc = _sweep(
        ["mission.py", "--seeds", "0:3", "--workers", "1", "--time-limit", "3", "--output", str(out)], tmp_path
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    rows = sorted(_rows(out), key=lambda r: r["index"])
    assert [(r["seed"], r["outcome"]) for r in rows] == [(0, "timed_out"), (1, "succeeded"), (2, "succeeded")]
    assert rows[0]["reason"].startswith("timed out: still running after 3 s") and rows[0]["exit_code"] == 124
    assert Path(rows[0]["record"]).is_file() and rows[0]["sim_time"] is not None
    assert "hanging" in (Path(rows[0]["run_dir"]) / "mission.log").read_text()
    # one simulator served the three trials: reset after the hung one, not replaced
    assert len(list((out / "runs" / "simulators").glob("sim-*.log"))) == 1
    leftovers = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True)
    assert leftovers.stdout == ""


def test_new_simulators_runs_each_trial_as_tb4_run_with_the_same_rows(tmp_path: Path) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    args = ["mission.py", "--seeds", "0:2", "--world", "warehouse,depot"]
    reused = _sweep([*args, "--output", "reused", "--workers", "1"], tmp_path)
    fresh = _sweep([*args, "--output", "fresh", "--new-simulators"], tmp_path)
    assert reused.returncode == fresh.returncode == 1, reused.stdout + reused.stderr + fresh.stdout + fresh.stderr

    def essence(folder: str) -> list[tuple]:
        return sorted(
            (r["key"], r["outcome"], r["exit_code"], r["reason"], r["bumps"]) for r in _rows(tmp_path / folder)
        )

    assert essence("reused") == essence("fresh")
    assert not (tmp_path / "fresh" / "runs" / "simulators").exists()  # no simulator of the sweep's own
    # the reused one: a simulator per world, each serving both of its seeds
    assert len(list((tmp_path / "reused" / "runs" / "simulators").glob("sim-*.log"))) == 2


DAEMON_END_WAIT = 30.0  # s Ray's daemons have to end once their head has


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@pytest.fixture(scope="module")
def ray_head(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A real Ray head of 2 CPUs on this machine, bound to 127.0.0.1, no dashboard, usage statistics off: its
    address; stopped (with every daemon it started) after the module's tests."""
    pytest.importorskip("ray")
    import sys

    port = _free_port()
    head = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "from ray.scripts.scripts import main; main()",
            "start",
            "--head",
            "--block",
            "--node-ip-address=127.0.0.1",
            f"--port={port}",
            "--include-dashboard=false",
            "--num-cpus=2",
            "--disable-usage-stats",
        ],
        env=_ray_environment(),
        cwd=tmp_path_factory.mktemp("ray-head"),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    try:
        assert wait_until(lambda: _listening(port) or head.poll() is not None, 60.0, period=0.2), "no Ray head in 60 s"
        assert head.poll() is None, f"the Ray head ended at start ({head.returncode})"
        yield f"127.0.0.1:{port}"
    finally:
        # --block: Ctrl-C stops the head and every daemon it started (they share its session)
        for sig, wait in ((signal.SIGINT, 30.0), (signal.SIGKILL, 10.0)):
            try:
                os.killpg(head.pid, sig)
                head.wait(timeout=wait)
                break
            except subprocess.TimeoutExpired:
                continue
    # no Ray daemon is left: they end a moment after the head (a stress run listed one just after it); one still
    # there after DAEMON_END_WAIT is killed by its id, and the test fails
    assert wait_until(lambda: not _session_members(head.pid), DAEMON_END_WAIT, period=0.2), _kill_all(
        _session_members(head.pid)
    )


def _session_members(session: int) -> list[int]:
    """The ids of the processes still in `session` (the Ray head's, which its daemons share)."""
    listing = subprocess.run(["ps", "-eo", "pid=,sid="], capture_output=True, text=True).stdout.split("\n")
    return [int(pid) for pid, sid in (line.split() for line in listing if line.strip()) if int(sid) == session]


def _kill_all(pids: list[int]) -> str:
    """SIGKILL each of `pids` (left behind); the assertion's message names them."""
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    return f"Ray daemons still running {DAEMON_END_WAIT:g} s after the head, killed: {pids}"


def _listening(port: int) -> bool:
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1.0):
            return True
    except OSError:
        return False


def _ray_environment() -> dict[str, str]:
    # Ray would resolve 127.0.0.1 to this machine's network address: told it is no cluster node, it stays on loopback
    return {**environment(), "RAY_USAGE_STATS_ENABLED": "0", "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0"}


def _simulator_logs(folder: Path) -> list[Path]:
    return sorted((folder / "runs" / "simulators").glob("*.log"))


def test_the_ray_backend_gives_the_local_rows(tmp_path: Path, ray_head: str) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    matrix = ["mission.py", "--seeds", "0:2", "--world", "warehouse,depot"]
    local = _sweep([*matrix, "--output", "local"], tmp_path)
    clustered = _sweep([*matrix, "--output", "ray", "--ray", ray_head], tmp_path, env=_ray_environment())
    assert clustered.returncode == 1, clustered.stdout + clustered.stderr

    def essence(folder: str) -> list[tuple]:
        rows = _rows(tmp_path / folder)
        return sorted((r["key"], r["outcome"], r["exit_code"], r["reason"], r["bumps"]) for r in rows)

    assert local.returncode == 1 and essence("ray") == essence("local")
    # the trials ran on actors that reset their simulators: their logs came back, fewer than the trials
    assert 1 <= len(_simulator_logs(tmp_path / "ray")) < 4
    failed = [r for r in _rows(tmp_path / "ray") if r["outcome"] == "failed"]
    assert len(failed) == 2
    for row in failed:  # its run folder came back: record, journal, picture; its replay command replays it here
        assert str(tmp_path / "ray") in row["record"] and Path(row["picture"]).is_file()
        assert (Path(row["run_dir"]) / "run.inputs.jsonl").is_file()
        assert row["replay"] == f"tb4 replay {row['record']}"
        _assert_replays(row)


def test_a_ray_sweep_runs_on_one_simulator_per_actor(tmp_path: Path, ray_head: str) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    proc = _sweep(
        ["mission.py", "--seeds", "0:6", "--output", "ray", "--ray", ray_head], tmp_path, env=_ray_environment()
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert sorted(r["seed"] for r in _rows(tmp_path / "ray")) == list(range(6))
    # two actors (one per CPU of the cluster), each one simulator reset between its trials: not one per trial
    assert 1 <= len(_simulator_logs(tmp_path / "ray")) <= 2


def test_a_ray_sweep_of_new_simulators_runs_tasks_and_its_failures_replay_here(tmp_path: Path, ray_head: str) -> None:
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    args = ["mission.py", "--seeds", "0:2", "--world", "depot", "--new-simulators", "--output", "ray"]
    args += ["--ray", ray_head]
    proc = _sweep(args, tmp_path, env=_ray_environment())
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert not _simulator_logs(tmp_path / "ray")  # each trial a `tb4 run` of its own, as a Ray task
    rows = _rows(tmp_path / "ray")
    assert [r["outcome"] for r in rows] == ["failed", "failed"]
    for row in rows:  # `tb4 run`'s folder came back, its journal with it
        assert str(tmp_path / "ray") in row["record"] and row["replay"] == f"tb4 replay {row['record']}"
        _assert_replays(row)


# The first time it runs, SIGKILLs the Ray actor that runs it (its fork server's parent), after writing down the
# actor's id and its children's (the simulator, the fork server); then ends at once.
KILL_ACTOR_ONCE_MISSION = textwrap.dedent(
    """\
    import json, os, signal, time
    marker = os.path.join(os.path.dirname(os.path.abspath(__file__)), "killed.json")
    if not os.path.exists(marker):
        def parent(pid):
            with open(f"/proc/{pid}/stat") as stat:
                return int(stat.read().rsplit(")", 1)[1].split()[1])
        actor = parent(os.getppid())
        children = []
        for task in os.listdir(f"/proc/{actor}/task"):
            with open(f"/proc/{actor}/task/{task}/children") as listed:
                children += [int(pid) for pid in listed.read().split()]
        with open(marker, "w") as out:
            json.dump({"actor": actor, "children": children}, out)
        os.kill(actor, signal.SIGKILL)
        time.sleep(60)
    """
)


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_a_ray_actor_killed_hard_errors_its_trial_and_takes_its_processes_with_it(
    tmp_path: Path, ray_head: str
) -> None:
    (tmp_path / "mission.py").write_text(KILL_ACTOR_ONCE_MISSION)
    proc = _sweep(
        ["mission.py", "--seeds", "0:4", "--time-limit", "60", "--output", "ray", "--ray", ray_head],
        tmp_path,
        env=_ray_environment(),
    )
    assert proc.returncode == 1, proc.stdout + proc.stderr
    rows = _rows(tmp_path / "ray")
    assert sorted(r["seed"] for r in rows) == list(range(4))  # the sweep went on: every trial has its row
    errored = [r for r in rows if r["outcome"] == "errored"]
    assert len(errored) == 1 and errored[0]["reason"].startswith("the Ray worker running it died"), errored
    assert sum(r["outcome"] == "succeeded" for r in rows) == 3
    from tb4.sweep.ray_backend import node_folder_prefix

    # the dead actor's folder on this node is gone too
    assert not list(Path(tempfile.gettempdir()).glob(node_folder_prefix(tmp_path / "ray") + "*"))
    killed = json.loads((tmp_path / "killed.json").read_text())
    assert len(killed["children"]) >= 2  # its simulator and its missions' fork server
    deadline = time.monotonic() + 30
    while any(_running(pid) for pid in killed["children"]):  # they end with the actor (end_with_parent)
        assert time.monotonic() < deadline, [pid for pid in killed["children"] if _running(pid)]
        time.sleep(0.2)


def test_ctrl_c_on_a_ray_sweep_ends_every_trial_and_its_actors_processes(tmp_path: Path, ray_head: str) -> None:
    from tb4.sweep.ray_backend import node_folder_prefix

    (tmp_path / "mission.py").write_text("import time\ntime.sleep(1.5)\n")
    out = tmp_path / "ray"
    args = [*TB4, "sweep", "mission.py", "--seeds", "0:12", "--output", str(out), "--json", "--ray", ray_head]
    code, stdout, seconds = _interrupt_after_a_row(args, tmp_path, _ray_environment(), out)
    assert code == 130 and seconds < 60
    assert json.loads(stdout.splitlines()[-1])["canceled"] is True and 1 <= len(_rows(out)) < 12
    # no simulator of its actors (their folders are named after the sweep), no fork server or mission is left
    prefix = node_folder_prefix(out)
    for pattern in (prefix, str(tmp_path / "mission.py")):
        leftovers = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True)
        assert leftovers.stdout == "", pattern


def test_an_unreachable_ray_address_is_a_clear_error_at_once(tmp_path: Path) -> None:
    pytest.importorskip("ray")
    (tmp_path / "mission.py").write_text(WORLD_MISSION)
    started = time.monotonic()
    proc = _sweep(["mission.py", "--seeds", "0:2", "--ray", f"127.0.0.1:{_free_port()}"], tmp_path, timeout=120)
    assert proc.returncode == 2 and "cannot reach the Ray cluster at '127.0.0.1:" in proc.stderr
    assert time.monotonic() - started < 30
