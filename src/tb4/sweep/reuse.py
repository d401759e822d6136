"""Fast trials: one simulator per worker, reset between trials instead of started anew, and each trial's mission
process started during the trial before it.

A trial as `tb4 run` runs it costs three new Python processes (the runner, the simulator, the mission), the
simulator's start (building the world and every ROS interface, DDS discovery) and the mission's start (imports,
rclpy, discovery): most of a short trial. Here a worker (`TrialHost`) keeps one `tb4 sim --control` and, for each
trial, asks it for a world reset with the trial's seed and record path (tb4.ros.simulator.serve_control: the same
reset as the simulator's reset_world service, SimLoop.reset in the core). The mission runs in its own new process as
under `tb4 run` (tb4.runner.tutorial_start), but that process is started while the previous trial runs: its imports,
rclpy and its DDS participant's discovery of the simulator are done when its start gate opens.

A trial needs a new simulator when its world, start battery, noise or localization differ from the last one's
(they are how the simulator was built), or when the simulator did not answer (ended, or hung past
CONTROL_TIMEOUT): it is then stopped by PID and replaced. A fleet, or an MCAP recording of every trial, runs each
trial as `tb4 run` (runner.run_trial_row). The rows are the same as `tb4 run`'s: the record is the simulator's, the
verdict and the `run` section are written by tb4.runner.session's helpers.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import shutil
import signal
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tb4.core.waits import Deadline, wait_until
from tb4.processes import (
    CONTROL_REPLY,
    READY_LINE,
    ManagedProcess,
    claim_domain_id,
    release_domain_id,
    remove_stale_shm,
    shm_snapshot,
    tb4_command,
)
from tb4.runner.fork_server import ForkServer
from tb4.sweep.matrix import Trial
from tb4.sweep.results import Row

__all__ = ["TrialHost", "SimulatorBuild", "reusable", "CONTROL_TIMEOUT"]

CONTROL_TIMEOUT = 30.0  # wall seconds for the simulator to answer a reset or a record write (a fraction of one)
SIM_START_TIMEOUT = 60.0  # wall seconds for a new simulator to be ready on a loaded machine
READ_PERIOD = 0.005  # wall seconds between two looks at the simulator's replies


def reusable(spec: Any) -> bool:
    """Whether a sweep's trials can share simulators: one robot (a fleet's world has no reset), no MCAP recording
    (a recording is checked against the counts of one simulator's whole life), and the reuse not turned off.

    Args:
        spec: the sweep (tb4.sweep.runner.SweepSpec).

    Returns:
        True when its trials can run on TrialHosts.
    """
    if not spec.reuse or spec.robots or spec.record:
        return False
    from tb4.runner.missions import MissionError, resolve_mission

    try:
        return not resolve_mission(spec.target, module=spec.module, cwd=Path(spec.cwd)).robots
    except MissionError:
        return False  # `tb4 run` says what is wrong with it, in each trial's row


@dataclass(frozen=True)
class SimulatorBuild:
    """What a simulator is built with: trials that differ only by seed share one (`of(trial)`)."""

    world: str
    battery: float | None
    exact: bool
    localization: str

    @classmethod
    def of(cls, trial: Trial) -> SimulatorBuild:
        return cls(trial.world, trial.battery, trial.exact, trial.localization)


class _ControlledSimulator:
    """`tb4 sim --control` in a domain of this worker's, answering resets and record writes."""

    def __init__(
        self, build: SimulatorBuild, seed: int, rate: str, env: dict[str, str], record: Path, log: Path
    ) -> None:
        from tb4.testing.simulator import SimSettings

        self.build = build
        settings = SimSettings(build.world, seed, rate, build.battery, build.exact, build.localization)
        args = tb4_command("sim", *settings.sim_arguments(), "--hold", "--control", "--record-run", str(record))
        self.process = ManagedProcess(args, env=env, log_path=log, stdin=subprocess.PIPE)
        self._offset = 0
        self._next_id = 0
        self._buffer = ""
        if not self.process.wait_for_output(READY_LINE, SIM_START_TIMEOUT):
            tail = " / ".join(self.process.output().strip().splitlines()[-3:])
            self.stop()
            raise RuntimeError(f"the simulator did not start: {tail}")

    def command(self, payload: dict[str, Any], timeout: float = CONTROL_TIMEOUT) -> dict[str, Any]:
        """Send one command and wait for its reply.

        Raises:
            RuntimeError: the simulator ended, refused, or did not answer within `timeout`.
        """
        self._next_id += 1
        ident = self._next_id
        stdin = self.process.popen.stdin
        assert stdin is not None
        try:
            stdin.write((json.dumps({"id": ident, **payload}) + "\n").encode())
            stdin.flush()
        except OSError as exc:
            raise RuntimeError(f"the simulator ended ({exc})") from None
        found: dict[str, Any] = {}

        def answered() -> bool:
            for line in self._new_lines():
                if line.startswith(CONTROL_REPLY):
                    reply = json.loads(line[len(CONTROL_REPLY) :])
                    if reply.get("id") == ident:
                        found.update(reply)
            return bool(found) or not self.process.alive()

        wait_until(answered, timeout, period=READ_PERIOD)
        if not found:
            state = "ended" if not self.process.alive() else f"did not answer within {timeout:g} s"
            raise RuntimeError(f"the simulator {state}")
        if not found.get("ok"):
            raise RuntimeError(f"the simulator refused: {found.get('error')}")
        return found

    def _new_lines(self) -> list[str]:
        log = self.process.log_path
        if log is None or not log.exists():
            return []
        with log.open("rb") as stream:
            stream.seek(self._offset)
            chunk = stream.read()
        self._offset += len(chunk)
        self._buffer += chunk.decode(errors="replace")
        *lines, self._buffer = self._buffer.split("\n")
        return lines

    def alive(self) -> bool:
        return self.process.alive()

    def stop(self) -> None:
        stdin = self.process.popen.stdin
        if stdin is not None:
            with contextlib.suppress(OSError):
                stdin.close()  # the end of its input stops it as Ctrl-C does
        self.process.stop(timeout=20.0)


class _WaitingMission:
    """A mission's process started ahead (forked by the host's fork server), held at its start gate
    (tb4.runner.tutorial_start)."""

    def __init__(self, server: ForkServer, argv: list[str], env: dict[str, str], world: str, cwd: str) -> None:
        from tb4.runner.tutorial_start import StartGate

        self.world = world
        self.gate = StartGate()
        # as `tb4 run`'s, started from the sweep's folder
        self.process: Any = self.gate.hand_over(lambda fd: server.spawn(argv, env, cwd, fd))

    def discard(self) -> None:
        """Close its gate (it ends without running) and end it."""
        from tb4.runner.session import end_mission_process

        self.gate.close()
        with contextlib.suppress(subprocess.TimeoutExpired):
            self.process.wait(timeout=5.0)
        end_mission_process(self.process, signal.SIGTERM, 5.0)


def _follow(proc: Any, deadline: Deadline, cancel: threading.Event) -> tuple[bytes, int | None]:
    """A mission's output until it ends, and its exit status (TIMED_OUT at `deadline`, None once `cancel` is set;
    it still runs then)."""
    from tb4.runner.session import TIMED_OUT

    output = bytearray()
    assert proc.stdout is not None
    fd, open_ = proc.stdout.fileno(), True
    while True:
        if open_:
            if select.select([fd], [], [], min(0.1, max(deadline.remaining(), 0.0)))[0]:
                chunk = os.read(fd, 65536)
                output += chunk
                open_ = bool(chunk)
        else:
            time.sleep(0.005)  # its output ended: its exit status is on its way
        code = proc.poll()
        # ended, and nothing more to read now (a process it left behind may hold the pipe: no wait for that)
        if code is not None and (not open_ or not select.select([fd], [], [], 0.0)[0]):
            return bytes(output), code if code >= 0 else 128 - code
        if cancel.is_set():
            return bytes(output), None
        if deadline.expired:
            return bytes(output), TIMED_OUT


class TrialHost:
    """One worker of a local sweep: a simulator reset between its trials, and the next mission process waiting.

    Args:
        spec: the sweep (tb4.sweep.runner.SweepSpec).
        folder: the sweep's runs folder (each trial's run goes into a folder of its own there).
        cancel: set to end the running trial (Ctrl-C).
    """

    def __init__(self, spec: Any, folder: Path, cancel: threading.Event) -> None:
        from tb4.runner.missions import resolve_mission

        self.spec = spec
        self.folder = Path(folder)
        self.cancel = cancel
        self.mission = resolve_mission(spec.target, module=spec.module, cwd=Path(spec.cwd))
        self.domain = claim_domain_id()
        self._shm_before = shm_snapshot()
        self._sim: _ControlledSimulator | None = None
        self._spare: _WaitingMission | None = None
        self._argv = [*self.mission.child_args(), *spec.arguments]
        self._server = ForkServer(self._argv, self._env(self.mission.world))
        self._logs = self.folder / "simulators"
        self._log_index = 0

    @property
    def world(self) -> str:
        """The world of its simulator ('' before the first)."""
        return self._sim.build.world if self._sim is not None else ""

    def close(self) -> None:
        """End its simulator and its waiting mission (by PID) and give its domain back."""
        if self._spare is not None:
            self._spare.discard()
            self._spare = None
        if self._sim is not None:
            self._sim.stop()
            self._sim = None
        self._server.close()
        if self.domain >= 0:
            release_domain_id(self.domain)
            self.domain = -1
        remove_stale_shm(self._shm_before)

    def _env(self, world: str) -> dict[str, str]:
        from tb4.processes import PARENT_ENV
        from tb4.runner.session import mission_environment

        return {**mission_environment(self.domain, world), PARENT_ENV: str(os.getpid())}

    def _simulator_for(self, trial: Trial, record: Path) -> _ControlledSimulator:
        """A simulator with `trial`'s world and seed, its record going to `record`: the last one reset, or a new one."""
        build = SimulatorBuild.of(trial)
        if self._sim is not None and self._sim.build == build and self._sim.alive():
            try:
                self._sim.command({"reset": {"seed": trial.seed, "record_run": str(record)}})
                return self._sim
            except RuntimeError:
                pass  # it ended or hung: a new one below
        if self._sim is not None:
            self._sim.stop()
            self._sim = None
        self._logs.mkdir(parents=True, exist_ok=True)
        self._log_index += 1
        log = self._logs / f"sim-{self.domain}-{self._log_index}.log"
        self._sim = _ControlledSimulator(build, trial.seed, self.spec.rate, self._env(trial.world), record, log)
        return self._sim

    def _mission_process(self, world: str) -> _WaitingMission:
        spare, self._spare = self._spare, None
        if spare is not None and spare.world == world and spare.process.poll() is None:
            return spare
        if spare is not None:
            spare.discard()
        return self._new_mission(world)

    def _new_mission(self, world: str) -> _WaitingMission:
        if not self._server.alive():
            self._server.close()
            self._server = ForkServer(self._argv, self._env(world))
        return _WaitingMission(self._server, self._argv, self._env(world), world, self.spec.cwd)

    def run(self, trial: Trial) -> tuple[Row, bool]:
        """Run one trial to its row; and whether it was canceled (no row to keep)."""
        from tb4.runner.session import (
            MISSION_STOP_GRACE,
            TIMED_OUT,
            RunOptions,
            RunOutcome,
            end_mission_process,
            finish_record,
            mission_reason,
        )
        from tb4.sweep.runner import errored_row, fill_row, trial_folder_name
        from tb4.testing.record import RunRecord

        row = errored_row(self.spec, trial, "")
        row.node = os.uname().nodename
        started = time.monotonic()
        trial_dir = self.folder / trial_folder_name(trial)
        trial_dir.mkdir(parents=True, exist_ok=True)
        record_path = trial_dir / "run.json"
        try:
            sim = self._simulator_for(trial, record_path)
        except RuntimeError as exc:
            row.reason, row.wall_time = str(exc), round(time.monotonic() - started, 3)
            return row, False
        waiting = self._mission_process(trial.world)
        waiting.gate.open()
        opened = time.monotonic()
        deadline = Deadline(self.spec.time_limit)
        # the next trial's process starts now: its imports and discovery overlap this trial
        self._spare = self._new_mission(trial.world)
        proc = waiting.process
        output, code = _follow(proc, deadline, self.cancel)
        if code is None:  # canceled: no row, no folder (a resumed sweep runs it again)
            end_mission_process(proc, signal.SIGINT, MISSION_STOP_GRACE)
            shutil.rmtree(trial_dir, ignore_errors=True)
            return row, True
        if code == TIMED_OUT and deadline.expired:
            end_mission_process(proc, signal.SIGINT, MISSION_STOP_GRACE)  # its Ctrl-C handling first
        wall_time = time.monotonic() - opened
        lines = output.decode(errors="replace").replace("\r", "\n").splitlines()
        (trial_dir / "mission.log").write_text("\n".join(lines) + "\n", encoding="utf-8")
        try:
            sim.command({"write": True})
        except RuntimeError as exc:
            row.reason = f"the simulator left no record: {exc}"
            row.wall_time = round(wall_time, 3)
            sim.stop()
            self._sim = None
            return row, False
        timed_out = code == TIMED_OUT and deadline.expired
        outcome = RunOutcome(
            code,
            mission_reason(code, self.mission, lines, self.spec.time_limit if timed_out else None),
            trial_dir,
            record=record_path,
            wall_time=wall_time,
        )
        options = RunOptions(
            world=trial.world,
            rate=self.spec.rate,
            seed=trial.seed,
            battery=trial.battery,
            output_dir=self.folder,
            tutorial_args=list(self.spec.arguments),
            exact=trial.exact,
            localization=trial.localization,
            time_limit=self.spec.time_limit,
            fail_on_bump=self.spec.fail_on_bump,
            picture=False,
        )
        finish_record(outcome, self.mission, options, trial.world)
        record = RunRecord.load(record_path, exit_code=outcome.exit_code, reason=outcome.reason)
        return fill_row(row, record, self.spec, trial_dir, started), False
