"""A simulator whose ROS teardown is stuck still ends, TEARDOWN_TIMEOUT after its run is finished, with its run
record written and its threads' stacks in its log; tb4 run's reason for the run then says so. Once a simulator
stopped by tb4 run waited in its teardown until it was killed, its run finished and its record written."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from tb4.processes import ManagedProcess
from tb4.ros.simulator import READY_LINE, TEARDOWN_TIMEOUT
from tb4.runner.session import simulator_failure

PROGRAM = Path(__file__).parent / "programs" / "sim_with_stuck_teardown.py"


def test_a_simulator_stuck_in_its_teardown_ends_at_the_bound_with_its_record_and_its_stacks(
    start_process: Callable[..., ManagedProcess], tmp_path: Path
) -> None:
    record = tmp_path / "run" / "run.json"
    record.parent.mkdir()
    sim = start_process(
        [sys.executable, str(PROGRAM), "--world", "depot", "--rate", "max", "--hold", "--record-run", str(record)],
        name="stuck-sim",
    )
    assert sim.wait_for_output(READY_LINE, timeout=60), sim.output()
    sim.interrupt()
    assert sim.wait_for_output("tb4 sim stopped", timeout=30), sim.output()
    try:
        code = sim.popen.wait(TEARDOWN_TIMEOUT + 20)  # the program's teardown alone would last 120 s
    except subprocess.TimeoutExpired:
        message = f"still running {TEARDOWN_TIMEOUT + 20:g} s after its run finished:\n{sim.output()}"
        raise AssertionError(message) from None
    log = sim.output()
    assert code == 1, (code, log)
    assert "Timeout (0:00:" in log and "in stuck_executor_shutdown" in log, log
    assert "sim_time" in json.loads(record.read_text())["summary"]  # the record was written before the teardown
    assert sim.log_path is not None
    assert simulator_failure(sim.log_path).startswith("the simulator hung on its way out, its run finished"), log


def test_a_simulator_that_failed_otherwise_is_said_to_have_failed(tmp_path: Path) -> None:
    log = tmp_path / "sim.log"
    log.write_text("tb4 sim: the simulation loop failed: RuntimeError('x')\n")
    assert simulator_failure(log) == f"the simulator failed (see {log})"
    assert simulator_failure(tmp_path / "missing.log").startswith("the simulator failed")
