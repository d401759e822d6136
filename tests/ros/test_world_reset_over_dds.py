"""reset_world over DDS: a simulator that ran a mission with one seed, reset to another, runs a mission to the same
result as a fresh simulator started with that seed; its clock starts again from 0 and its record holds the new run."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from std_srvs.srv import Trigger

from tb4.processes import ManagedProcess

from .rosclient import RosClient

SIM = ("--world", "warehouse", "--rate", "max", "--hold")


def _nav_to_pose(env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "tb4.tutorials.nav_to_pose"],
        env=env,
        capture_output=True,
        text=True,
        timeout=180,
        stdin=subprocess.DEVNULL,
    )


def _outcome(record_path: Path) -> dict:
    record = json.loads(record_path.read_text())
    results = [(e["action"], e["status"]) for e in record["events"] if e["type"] == "result"]
    t0, x, y, _yaw = record["trajectory"][0]
    _t, x1, y1, yaw1 = record["trajectory"][-1]
    return {"results": results, "start": (t0, x, y), "end": (x1, y1, yaw1), "seed": record["summary"]["seed"]}


def _stop(sim: ManagedProcess, record_path: Path) -> None:
    sim.stop(timeout=20)
    assert record_path.is_file(), sim.output()[-3000:]


def test_a_reset_simulator_runs_a_mission_as_a_fresh_one(start_simulator, ros_env, tmp_path: Path) -> None:
    fresh_record = tmp_path / "fresh.json"
    fresh = start_simulator(*SIM, "--seed", "5", "--record-run", str(fresh_record), name="fresh")
    first = _nav_to_pose(ros_env)
    assert first.returncode == 0, first.stdout + first.stderr
    _stop(fresh, fresh_record)

    reused_record = tmp_path / "reused.json"
    reused = start_simulator(*SIM, "--seed", "9", "--record-run", str(reused_record), name="reused")
    other = _nav_to_pose(ros_env)  # another seed's run first: the reset must undo all of it
    assert other.returncode == 0, other.stdout + other.stderr
    client = RosClient("reset_client")
    try:
        seed = Parameter(name="seed", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER, integer_value=5))
        set_seed = client.service(
            SetParameters, "/turtlebot4_sim/set_parameters", SetParameters.Request(parameters=[seed])
        )
        assert set_seed.results[0].successful
        reply = client.service(Trigger, "/reset_world", Trigger.Request(), timeout=20.0)
        assert reply.success and "seed 5" in reply.message, reply.message
    finally:
        client.close()
    again = _nav_to_pose(ros_env)
    assert again.returncode == 0, again.stdout + again.stderr
    _stop(reused, reused_record)

    expected, got = _outcome(fresh_record), _outcome(reused_record)
    assert got["seed"] == expected["seed"] == 5
    assert got["results"] == expected["results"]  # the record holds the new run only: the same goals, same ends
    assert got["start"][0] < 5.0  # sim time went back to 0 at the reset
    assert got["start"][1:] == expected["start"][1:]  # on the dock again
    # the same goal reached; the paths differ only by when the goal came in during the start-up hold (wall time)
    assert abs(got["end"][0] - expected["end"][0]) < 0.3 and abs(got["end"][1] - expected["end"][1]) < 0.3
