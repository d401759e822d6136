"""`tb4 run NAME --attach`: the tutorial runs against a simulator (or robot) that is already up, which it does not
start or stop; the run monitor still follows it."""

from __future__ import annotations

import json
import subprocess

from tb4.processes import tb4_command


def test_run_attach_drives_the_running_simulator_and_leaves_it_running(start_simulator, ros_env, tmp_path) -> None:
    sim = start_simulator("--rate", "max", "--hold", "--world", "warehouse")
    done = subprocess.run(
        tb4_command("run", "nav_to_pose", "--attach", "--json", "--output-dir", str(tmp_path)),
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=180,
    )
    events = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    assert done.returncode == 0, (done.stdout[-2000:], done.stderr[-2000:])
    assert events[-1]["event"] == "end" and events[-1]["exit_code"] == 0
    assert any(e.get("event") == "log" and "Goal succeeded!" in e.get("line", "") for e in events)
    assert sim.alive()  # attached: the simulator was not ours to stop
