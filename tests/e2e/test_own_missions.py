"""A user's own mission under `tb4 run`, as a user runs it: a script in a folder of theirs that imports nothing of
ours but upstream's paths, its exit code, its run folder, its recording; and what goes wrong with one."""

from __future__ import annotations

import json
import signal
import subprocess
import textwrap
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from .tutorial_runs import TB4, environment, record_of, run_json

MISSION = textwrap.dedent(
    """\
    #!/usr/bin/env python3
    # The user's mission, as it runs on the robot: undock, one waypoint, and an exit code of its own.
    import sys

    import rclpy
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator


    def main():
        rclpy.init()
        navigator = TurtleBot4Navigator()
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startFollowWaypoints([navigator.getPoseStamped([2.0, 1.0], TurtleBot4Directions.EAST)])
        print("mission arguments:", sys.argv[1:], flush=True)
        rclpy.shutdown()
        return int(sys.argv[sys.argv.index("--exit") + 1]) if "--exit" in sys.argv else 0


    if __name__ == "__main__":
        sys.exit(main())
    """
)


def _tb4(args: list[str], cwd: Path, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*TB4, *args],
        cwd=cwd,
        env=environment(),
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


def test_a_users_script_runs_with_its_own_exit_code_run_folder_and_recording(tmp_path: Path) -> None:
    (tmp_path / "my_mission.py").write_text(MISSION)
    mcap = tmp_path / "run.mcap"
    code, events, _ = run_json(
        [str(tmp_path / "my_mission.py"), "--seed", "3", "--record", str(mcap)],
        tmp_path / "runs",
        mission_args=["--exit", "3", "--seed", "x"],
    )
    assert code == 3  # the script's own
    end = events[-1]
    assert end["exit_code"] == 3 and end["reason"] == "the script exited with code 3", end
    run_dir = Path(end["run_dir"])
    assert run_dir.name.startswith("my_mission-") and {"run.png", "run.json", "sim.log"} <= {
        p.name for p in run_dir.iterdir()
    }
    record = record_of(events)
    assert record["run"]["mission"] == {
        "name": "my_mission",
        "kind": "script",
        "target": str(tmp_path / "my_mission.py"),
    }
    assert record["run"]["seed"] == 3 and record["summary"]["seed"] == 3 and record["run"]["exit_code"] == 3
    assert record["run"]["arguments"] == ["--exit", "3", "--seed", "x"]  # after --: the script's, not ours
    assert Path(record["world_file"]).name == "warehouse.yaml"  # tb4 render finds any world the run used
    assert any(e.get("action") == "follow_waypoints" and e.get("status") == "succeeded" for e in record["events"])
    with mcap.open("rb") as stream:
        topics = {channel.topic for _, channel, _ in make_reader(stream).iter_messages()}
    assert {"/map", "/odom", "/tf"} <= topics


def test_a_mission_module_runs_from_the_current_folder(tmp_path: Path) -> None:
    package = tmp_path / "missions"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "short.py").write_text("import sys\nprint('module ran with', sys.argv[1:])\nsys.exit(0)\n")
    proc = _tb4(["run", "-m", "missions.short", "--quiet", "--output-dir", str(tmp_path / "runs"), "a"], tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.strip().endswith("tb4 run short succeeded")


@pytest.mark.parametrize(
    ("args", "files", "expected"),
    [
        (["run", "nosuch.py"], {}, "no such file: nosuch.py"),
        (["run", "broken.py"], {"broken.py": "x = (\n"}, "does not compile (line 1"),
        (["run", "nav_to_pos"], {}, "did you mean 'nav_to_pose'"),
        (["run", "-m", "no_such_package.mission"], {}, "cannot find module 'no_such_package.mission'"),
        (["run", "folder"], {"folder/x": ""}, "is not a file"),
        (["run", "nul.py"], {"nul.py": "x = 1\0"}, "null bytes"),
        (["render", "."], {}, "is not a run folder (no run.json in it)"),
        (["render", "run.json"], {"run.json": "{not json"}, "is not a run record"),
    ],
)
def test_what_cannot_run_is_said_before_anything_starts(
    tmp_path: Path, args: list[str], files: dict[str, str], expected: str
) -> None:
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    started = time.monotonic()
    proc = _tb4(args, tmp_path, timeout=60)
    assert proc.returncode == 2
    assert expected in proc.stdout + proc.stderr
    assert not (tmp_path / "runs").exists()  # no simulator, no run folder
    assert time.monotonic() - started < 30


def test_a_mission_that_never_ends_is_ended_at_its_time_limit(tmp_path: Path) -> None:
    (tmp_path / "forever.py").write_text(
        "import time\nprint('working', flush=True)\nwhile True:\n    time.sleep(0.1)\n"
    )
    started = time.monotonic()
    code, events, _ = run_json([str(tmp_path / "forever.py"), "--time-limit", "2"], tmp_path / "runs", timeout=120)
    assert code == 124
    assert events[-1]["reason"].startswith("timed out: still running after 2 s"), events[-1]
    assert time.monotonic() - started < 60
    record = record_of(events)
    assert record["run"]["exit_code"] == 124
    assert "tb4 sim stopped" in (Path(events[-1]["run_dir"]) / "sim.log").read_text()


def test_a_crashing_mission_fails_with_its_exception(tmp_path: Path) -> None:
    (tmp_path / "crash.py").write_text("places = {'dock': 1}\nplaces['shelf']\n")
    code, events, _ = run_json([str(tmp_path / "crash.py")], tmp_path / "runs")
    assert code == 1
    assert events[-1]["reason"] == "exit code 1: KeyError: 'shelf'"


def test_bumps_are_news_and_can_fail_a_run(tmp_path: Path) -> None:
    code, events, _ = run_json(["bump_and_go", "--fail-on-bump"], tmp_path / "runs")
    assert code == 1
    bumps = [e for e in events if e["event"] == "bump"]
    record = record_of(events)
    recorded = [e for e in record["events"] if e["type"] == "bump"]
    said = (events[-1]["reason"], (Path(events[-1]["run_dir"]) / "sim.log").read_text()[-2000:])
    assert len(recorded) == 3 and record["run"]["bumps"] == 3 and events[-1]["bumps"] == 3, said
    assert 1 <= len(bumps) <= 3  # the monitor's live news (a press may fall before it matched the topic)
    first = recorded[0]
    assert events[-1]["reason"].startswith(f"bumped 3 time(s) (--fail-on-bump); the first at ({first['x']:.2f}")
    picture = _tb4(["render", events[-1]["run_dir"], "-o", str(tmp_path / "again.png")], tmp_path)
    assert picture.returncode == 0 and (tmp_path / "again.png").stat().st_size > 10_000


def test_tb4_sim_records_to_mcap_from_its_start(tmp_path: Path) -> None:
    from tb4.processes import ManagedProcess

    mcap = tmp_path / "sim.mcap"
    log = tmp_path / "sim.log"
    sim = ManagedProcess([*TB4, "sim", "--rate", "max", "--record", str(mcap)], env=environment(), log_path=log)
    try:
        assert sim.wait_for_output("tb4 sim ready", 60), sim.output()
    finally:
        sim.stop(timeout=20)
    assert "recording without" not in sim.output()
    with mcap.open("rb") as stream:
        counts: dict[str, int] = {}
        for _, channel, _ in make_reader(stream).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts.get("/map") == 1 and counts.get("/tf_static", 0) >= 1 and counts.get("/clock", 0) > 0


def test_a_misspelt_place_fails_the_mission_before_the_robot_moves(tmp_path: Path) -> None:
    (tmp_path / "places_mission.py").write_text(
        textwrap.dedent(
            """\
            import rclpy
            from tb4.places import Places
            from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Navigator

            rclpy.init()
            navigator = TurtleBot4Navigator()
            places = Places.of_robot(navigator.get_namespace())
            places.require("office", "packing statoin")
            navigator.undock()
            navigator.startToPose(places.pose("office", navigator))
            """
        )
    )
    code, events, _ = run_json([str(tmp_path / "places_mission.py")], tmp_path / "runs")
    assert code == 1
    assert "UnknownPlace: no place called 'packing statoin'" in events[-1]["reason"]
    assert "did you mean 'packing station'?" in events[-1]["reason"]
    record = record_of(events)
    assert [e for e in record["events"] if e["type"] == "goal"] == []  # nothing was sent: not even the undock


LONG_DRIVE = textwrap.dedent(
    """\
    import rclpy
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

    rclpy.init()
    navigator = TurtleBot4Navigator()
    navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
    navigator.waitUntilNav2Active()
    navigator.undock()
    print("driving", flush=True)
    navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST))
    print("arrived", flush=True)
    """
)


@pytest.mark.parametrize(("sig", "code"), [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_mid_goal_stops_the_run_its_mission_and_simulator(tmp_path: Path, sig: int, code: int) -> None:
    (tmp_path / "drive.py").write_text(LONG_DRIVE)
    out = tmp_path / "runs"
    proc = subprocess.Popen(
        [*TB4, "run", str(tmp_path / "drive.py"), "--rate", "2", "--output-dir", str(out)],
        env=environment(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        stdin=subprocess.DEVNULL,
    )
    assert proc.stdout is not None
    deadline = time.monotonic() + 90
    while "driving" not in proc.stdout.readline():
        assert time.monotonic() < deadline and proc.poll() is None, "the mission never started driving"
    time.sleep(1.0)
    sent = time.monotonic()
    proc.send_signal(sig)
    output, _ = proc.communicate(timeout=30)
    # about 1 s on a quiet machine; the bound leaves room for a loaded CI machine (before, SIGTERM was ignored)
    assert proc.returncode == code and time.monotonic() - sent < 6.0, output
    assert "arrived" not in output
    leftovers = subprocess.run(["pgrep", "-f", str(tmp_path)], capture_output=True, text=True)
    assert leftovers.stdout == ""  # neither the simulator nor the mission outlived tb4 run
    record = json.loads(next(out.glob("drive-*/run.json")).read_text())
    assert [
        e["status"] for e in record["events"] if e.get("action") == "navigate_to_pose" and e["type"] == "result"
    ] == ["canceled"]
