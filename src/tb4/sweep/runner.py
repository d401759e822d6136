"""Running a sweep: every trial of the matrix as `tb4 run` in a DDS domain of its own, several at once on this
machine (or as Ray tasks on a cluster: ray_backend.py), each row saved as it ends.

A trial that succeeds leaves only its row (its run folder is removed unless `keep_runs`); a failure keeps its run
folder with the picture, the record and (with `record`) the MCAP, and its row says how to run it again. Ctrl-C
(`Sweep.cancel`) ends the running trials, keeps every finished row, and a sweep started again with `resume`
runs only the trials without one.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import socket
import threading
import time
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from tb4.sweep.matrix import Trial
from tb4.sweep.results import ERRORED, FAILED, SUCCEEDED, TIMED_OUT, ResultsTable, Row

__all__ = [
    "SweepSpec",
    "Sweep",
    "SweepError",
    "run_trial_row",
    "replay_command",
    "errored_row",
    "default_workers",
    "fill_row",
    "trial_folder_name",
]

SPEC_FILE = "sweep.json"


class SweepError(RuntimeError):
    """The sweep cannot start: its folder holds another sweep, or results it was not told to resume."""


@dataclass
class SweepSpec:
    """What a sweep runs: the mission, its arguments, the trials, and how each trial runs.

    Attributes:
        target: a tutorial name, a script path, or with `module`, a dotted module name.
        trials: the matrix (tb4.sweep.matrix.build_matrix).
        arguments: the mission's own arguments.
        module: `target` is a module.
        rate: the simulators' rate ("max").
        robots: a fleet mission's robot count.
        time_limit: wall seconds a trial may run before it is ended and counted as timed out.
        record: record every trial to MCAP (kept for the failures).
        fail_on_bump: a bump fails a trial.
        keep_runs: keep the run folders of the trials that succeeded too.
        cwd: the folder a relative script path or a module is found from.
        reuse: on this machine, reset one simulator per worker between trials (tb4.sweep.reuse) where a trial
            allows it; False runs every trial as a `tb4 run` of its own.
    """

    target: str
    trials: list[Trial]
    arguments: list[str] = field(default_factory=list)
    module: bool = False
    rate: str = "max"
    robots: int = 0
    time_limit: float = 600.0
    record: bool = False
    fail_on_bump: bool = False
    keep_runs: bool = False
    cwd: str = field(default_factory=os.getcwd)
    reuse: bool = True

    def identity(self) -> dict[str, Any]:
        """What makes two sweeps the same sweep (for --resume): the mission and the matrix, not how it runs."""
        keys = "\n".join(trial.key for trial in self.trials)
        return {
            "target": self.target,
            "module": self.module,
            "arguments": list(self.arguments),
            "robots": self.robots,
            "rate": self.rate,
            "fail_on_bump": self.fail_on_bump,
            "trials": len(self.trials),
            "matrix": hashlib.sha256(keys.encode()).hexdigest()[:16],
        }

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data["trials"] = [trial.as_dict() for trial in self.trials]
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SweepSpec:
        values = dict(data)
        values["trials"] = [Trial(**trial) for trial in data["trials"]]
        return cls(**values)


def replay_command(spec: SweepSpec, trial: Trial) -> str:
    """The `tb4 run` command line that runs `trial` again, as a person types it."""
    import shlex

    parts = ["tb4", "run", *(["-m"] if spec.module else []), spec.target, "--seed", str(trial.seed)]
    parts += ["--world", trial.world]
    if trial.battery is not None:
        parts += ["--battery", f"{trial.battery:g}"]
    if trial.exact:
        parts.append("--exact")
    if trial.localization != "amcl":
        parts += ["--localization", trial.localization]
    if spec.robots:
        parts += ["--robots", str(spec.robots)]
    if spec.fail_on_bump:
        parts.append("--fail-on-bump")
    if spec.arguments:
        parts += ["--", *spec.arguments]
    return shlex.join(parts)


def run_trial_row(
    spec: SweepSpec, trial: Trial, folder: Path, cancel: threading.Event | None = None
) -> tuple[Row, bool]:
    """Run one trial to its row (on whichever machine this runs); and whether it was canceled (no row to keep).

    The run folder goes under `folder/KEY`; a success's is removed unless `spec.keep_runs`; a failure's keeps its
    record, its picture (drawn here) and its MCAP.
    """
    from tb4.testing.simulator import SimSettings
    from tb4.testing.trials import TrialCanceled, TrialError, run_mission

    settings = SimSettings(
        world=trial.world,
        seed=trial.seed,
        rate=spec.rate,
        battery=trial.battery,
        exact=trial.exact,
        localization=trial.localization,
        robots=spec.robots,
    )
    trial_dir = folder / trial_folder_name(trial)
    row = errored_row(spec, trial, "")
    row.node = socket.gethostname()
    started = time.monotonic()
    try:
        record = run_mission(
            spec.target,
            spec.arguments,
            settings,
            trial_dir,
            module=spec.module,
            time_limit=spec.time_limit,
            record=spec.record,
            fail_on_bump=spec.fail_on_bump,
            cwd=spec.cwd,
            picture=False,
            cancel=cancel,
        )
    except TrialCanceled:
        shutil.rmtree(trial_dir, ignore_errors=True)
        return row, True
    except (TrialError, OSError, ValueError) as exc:
        row.reason = str(exc)
        row.wall_time = round(time.monotonic() - started, 3)
        return row, False
    return fill_row(row, record, spec, trial_dir, started), False


def fill_row(row: Row, record: Any, spec: SweepSpec, trial_dir: Path, started: float) -> Row:
    """A trial's row from its run record (tb4.testing.RunRecord): outcome, reason, times, bumps, clearance,
    localization error; a success's folder is removed (unless `spec.keep_runs`), a failure's keeps its picture.

    Args:
        row: the trial's row so far (tb4.sweep.runner.errored_row).
        record: the run's record, with its exit code and reason.
        spec: the sweep.
        trial_dir: the folder the trial's run went into.
        started: time.monotonic() when the trial started (its wall time when the record has none).

    Returns:
        `row`, filled in.
    """
    from tb4.testing.trials import TIMED_OUT as TIMED_OUT_CODE

    row.exit_code = record.exit_code
    row.reason = record.reason
    row.outcome = SUCCEEDED if record.exit_code == 0 else TIMED_OUT if record.exit_code == TIMED_OUT_CODE else FAILED
    row.sim_time = round(record.sim_time, 3)
    row.wall_time = record.wall_time if record.wall_time is not None else round(time.monotonic() - started, 3)
    row.bumps = len(record.bumps)
    closest = record.min_clearance()
    row.min_clearance = None if closest is None else round(closest[0], 4)
    error = record.localization_error
    row.localization_error = None if not error else error.get("mean_position_error")
    if row.outcome == SUCCEEDED and not spec.keep_runs:
        shutil.rmtree(trial_dir, ignore_errors=True)
        return row
    row.run_dir, row.record = str(record.run_dir), str(record.path)
    row.mcap = str(record.mcap) if record.mcap else ""
    row.replay = record.replay_command or row.replay  # the run itself, exactly, from its journal
    if row.outcome != SUCCEEDED:
        row.picture = _draw(record.run_dir)
    return row


def default_workers(spec: SweepSpec) -> int:
    """Trials at once when the user names no number: one per core, and two more when the trials reuse simulators
    (tb4.sweep.reuse). A reused trial's processes spend part of it waiting (the mission's DDS discovery of the
    simulator, its goal responses, the reset between two trials), and with one worker per core the cores idle
    then; the more a trial's CPU is cut, the larger that idle share, and two workers more fill it.

    Args:
        spec: the sweep.

    Returns:
        The number of workers.
    """
    from tb4.sweep.reuse import reusable

    cores = os.cpu_count() or 1
    return cores + 2 if reusable(spec) else cores


def errored_row(spec: SweepSpec, trial: Trial, reason: str) -> Row:
    """The row of a trial that could not run or whose worker died."""
    return Row(
        key=trial.key,
        **asdict(trial),
        outcome=ERRORED,
        reason=reason,
        replay=replay_command(spec, trial),
    )


def trial_folder_name(trial: Trial) -> str:
    """The folder a trial's run goes into: its index, world, seed and settings (sorted as the matrix)."""
    battery = "" if trial.battery is None else f"-b{trial.battery:g}"
    flags = ("-exact" if trial.exact else "") + ("" if trial.localization == "amcl" else f"-{trial.localization}")
    return f"{trial.index:06d}-{trial.world}-s{trial.seed}{battery}{flags}"


def _draw(run_dir: Path) -> str:
    try:
        from tb4.runner.picture import render_record

        return str(render_record(run_dir))
    except Exception:  # noqa: BLE001 - no picture ([render] missing, an odd record) is no reason to lose the row
        return ""


class Sweep:
    """A sweep over `spec.trials`, its results in `folder`.

    Args:
        spec: what to run.
        folder: where results.jsonl, results.csv, summary.json/.txt and the failures' run folders go.
        workers: trials at once on this machine (default: `default_workers`).
        resume: continue the sweep whose rows `folder` already holds (only trials without a row run).
        ray_address: run the trials as Ray tasks on this cluster ("auto", "HOST:PORT"; "" = a local one).

    Raises:
        SweepError: `folder` holds another sweep, or this one's rows without `resume`.
    """

    def __init__(
        self,
        spec: SweepSpec,
        folder: Path,
        workers: int | None = None,
        resume: bool = False,
        ray_address: str | None = None,
    ) -> None:
        self.spec = spec
        self.folder = Path(folder).resolve()
        self.workers = max(1, workers or default_workers(spec))
        self.ray_address = ray_address
        self._cancel = threading.Event()
        self.table = self._open(resume)
        done = self.table.done_keys()
        self.pending = [trial for trial in spec.trials if trial.key not in done]

    def _open(self, resume: bool) -> ResultsTable:
        self.folder.mkdir(parents=True, exist_ok=True)
        spec_path = self.folder / SPEC_FILE
        if spec_path.is_file():
            try:
                existing = json.loads(spec_path.read_text(encoding="utf-8"))
            except ValueError:
                raise SweepError(f"{spec_path} is not a sweep definition: choose another folder") from None
            if existing.get("identity") != self.spec.identity():
                raise SweepError(
                    f"{self.folder} holds another sweep ({existing.get('identity', {}).get('target', '?')}, "
                    f"{existing.get('identity', {}).get('trials', '?')} trials): choose another --output folder"
                )
            if not resume and (self.folder / "results.jsonl").is_file():
                raise SweepError(f"{self.folder} holds this sweep's results already: --resume continues it")
        elif any(self.folder.iterdir()):
            raise SweepError(f"{self.folder} is not empty and holds no sweep: choose another --output folder")
        spec_path.write_text(
            json.dumps({"identity": self.spec.identity(), "spec": self.spec.to_dict()}, indent=1), encoding="utf-8"
        )
        return ResultsTable.load(self.folder) if resume else ResultsTable(self.folder)

    def cancel(self) -> None:
        """End the running trials (from any thread, e.g. on Ctrl-C); their rows are not written."""
        self._cancel.set()

    @property
    def canceled(self) -> bool:
        return self._cancel.is_set()

    def run(self, on_row: Callable[[Row], None] | None = None) -> ResultsTable:
        """Run every pending trial; the table (also on disk). `on_row` is called with each row as it is kept."""
        if self.ray_address is not None:
            from tb4.sweep.ray_backend import run_on_ray

            run_on_ray(self, on_row)
        else:
            self._run_local(on_row)
        self.table.write_csv()
        self.table.write_summary()
        return self.table

    def keep(self, row: Row, on_row: Callable[[Row], None] | None) -> None:
        self.table.add(row)
        if on_row is not None:
            on_row(row)

    def _run_local(self, on_row: Callable[[Row], None] | None) -> None:
        from tb4.sweep.reuse import TrialHost, reusable

        queue = list(self.pending)
        runs = self.folder / "runs"
        hosts: list[TrialHost] = []
        idle: list[TrialHost] = []
        hosts_lock = threading.Lock()
        reuse = reusable(self.spec)

        def run_on_host(trial: Trial) -> tuple[Row, bool]:
            """The trial on an idle host, the one that ran its world last if any (no new simulator)."""
            with hosts_lock:
                host = next((h for h in idle if h.world == trial.world), idle[0] if idle else None)
                if host is not None:
                    idle.remove(host)
            if host is None:
                host = TrialHost(self.spec, runs, self._cancel)
                with hosts_lock:
                    hosts.append(host)
            try:
                return host.run(trial)
            finally:
                with hosts_lock:
                    idle.append(host)

        def run_one(trial: Trial) -> tuple[Row, bool]:
            return run_on_host(trial) if reuse else run_trial_row(self.spec, trial, runs, self._cancel)

        try:
            self._run_pool(queue, run_one, on_row)
        finally:
            for host in hosts:
                host.close()

    def _run_pool(
        self,
        queue: list[Trial],
        run_one: Callable[[Trial], tuple[Row, bool]],
        on_row: Callable[[Row], None] | None,
    ) -> None:
        with ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix="tb4-sweep") as pool:
            running: dict[Future[tuple[Row, bool]], Trial] = {}
            while queue or running:
                while queue and len(running) < self.workers and not self.canceled:
                    trial = queue.pop(0)
                    running[pool.submit(run_one, trial)] = trial
                if not running:
                    break  # canceled with nothing left running
                finished, _ = wait(running, timeout=0.5, return_when=FIRST_COMPLETED)
                for future in finished:
                    trial = running.pop(future)
                    try:
                        row, canceled = future.result()
                    except Exception as exc:  # noqa: BLE001 - a worker that died: its trial errored, the sweep goes on
                        row, canceled = errored_row(self.spec, trial, f"the worker failed: {exc!r}"), False
                    if not canceled:
                        self.keep(row, on_row)
