"""Trials: run a mission (a script, a module, a tutorial, or a Python callable given a navigator) in a simulator of
its own and get its RunRecord back. Each trial claims a DDS domain no other run on the machine holds, so trials
in parallel (pytest-xdist workers, a sweep) never hear each other, and ends every process it started.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tb4.processes import PARENT_ENV, claim_domain_id, release_domain_id, ros_environment, tb4_command
from tb4.testing.record import RunRecord
from tb4.testing.simulator import SimSettings, Simulator

__all__ = ["run_mission", "run_trial", "TrialError", "TrialCanceled", "TIMED_OUT"]

TIMED_OUT = 124  # the exit code of a trial ended at its time limit (tb4 run's, and `timeout`'s)
RUNNER_GRACE = 120.0  # wall seconds past a trial's own limit before the runner itself is ended


class TrialError(RuntimeError):
    """The trial could not run at all (tb4 run refused it, or left no record); the message says why."""


class TrialCanceled(RuntimeError):
    """The trial was ended by its `cancel` event before it finished (a sweep interrupted)."""


def _settings_arguments(settings: SimSettings) -> list[str]:
    args = settings.sim_arguments()
    if settings.robots:
        args += ["--robots", str(settings.robots)]
    return args


def run_mission(
    target: str | Path,
    arguments: Sequence[str] = (),
    settings: SimSettings | None = None,
    output_dir: str | Path | None = None,
    *,
    module: bool = False,
    time_limit: float | None = None,
    record: bool = False,
    fail_on_bump: bool = False,
    cwd: str | Path | None = None,
    picture: bool = True,
    cancel: threading.Event | None = None,
) -> RunRecord:
    """Run a mission with `tb4 run` in a domain of its own; its record.

    Args:
        target: a script path, a tutorial name, or with `module`, a dotted module name.
        arguments: the mission's own arguments (given after `--`).
        settings: the simulator's settings (world, seed, battery, noise, ...).
        output_dir: where the run folder goes (default: a new temporary folder).
        module: `target` is a module (`tb4 run -m`).
        time_limit: wall seconds the mission may run (then it ends with TIMED_OUT).
        record: also record the run's topics to MCAP (run.mcap in the run folder).
        fail_on_bump: a bump fails the run.
        cwd: the folder relative paths and modules are found from.
        picture: draw the run's picture (a sweep draws only its failures', afterwards).
        cancel: set from another thread to end the run (Ctrl-C on a sweep).

    Returns:
        The RunRecord, with exit_code, reason, picture and mcap set.

    Raises:
        TrialError: tb4 run refused the mission (no such file, does not compile...) or left no record.
        TrialCanceled: `cancel` was set before it ended.
    """
    settings = settings or SimSettings()
    out = Path(output_dir) if output_dir is not None else Path(tempfile.mkdtemp(prefix="tb4-trial-"))
    args = tb4_command("run", *(["-m"] if module else []), str(target), *_settings_arguments(settings))
    args += ["--json", "--output-dir", str(out.resolve())]
    mcap = out.resolve() / f"{Path(str(target)).stem}.mcap" if record else None
    if mcap is not None:
        args += ["--record", str(mcap)]
    if time_limit is not None:
        args += ["--time-limit", str(time_limit)]
    if fail_on_bump:
        args.append("--fail-on-bump")
    if not picture:
        args.append("--no-picture")
    args += ["--", *arguments]
    domain = claim_domain_id()
    try:
        env = ros_environment(domain)
        env[PARENT_ENV] = str(os.getpid())  # tb4 run ends with this process (a sweep's worker that dies)
        stdout, stderr = _run_bounded(args, env, cwd, time_limit, cancel)
    finally:
        release_domain_id(domain)
    events = [json.loads(line) for line in stdout.splitlines() if line.startswith("{")]
    end = next((e for e in reversed(events) if e.get("event") == "end"), None)
    if end is None or not end.get("record"):
        said = (end or {}).get("reason") or stderr.strip() or stdout.strip()
        raise TrialError(f"tb4 run {target}: no run record: {said[-1500:]}")
    return RunRecord.load(
        end["record"],
        exit_code=int(end["exit_code"]),
        reason=str(end["reason"]),
        picture=Path(end["picture"]) if end.get("picture") else None,
        mcap=Path(end["mcap"]) if end.get("mcap") else None,
    )


def _run_bounded(
    args: list[str],
    env: dict[str, str],
    cwd: str | Path | None,
    time_limit: float | None,
    cancel: threading.Event | None = None,
) -> tuple[str, str]:
    """Run `tb4 run` to its end; past its own limit plus RUNNER_GRACE (or 30 min without one), or once `cancel` is
    set, end its group (Ctrl-C first: it stops its simulator and mission itself)."""
    bound = (time_limit or 1800.0) + RUNNER_GRACE
    proc = subprocess.Popen(
        args,
        env=env,
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    deadline = time.monotonic() + bound
    try:
        while True:
            try:
                return proc.communicate(timeout=0.5 if cancel is not None else bound)
            except subprocess.TimeoutExpired:
                if cancel is not None and cancel.is_set():
                    _end_group(proc)
                    raise TrialCanceled("the trial was canceled") from None
                if time.monotonic() >= deadline:
                    _end_group(proc)
                    raise TrialError(f"tb4 run did not end within {bound:g} s: ended it (pid {proc.pid})") from None
    except BaseException:
        if proc.poll() is None:
            _end_group(proc)
        raise


def _end_group(proc: subprocess.Popen[str]) -> None:
    """Ctrl-C to the run's process group (tb4 run stops its mission and simulator), then SIGKILL after 20 s."""
    for sig, wait in ((signal.SIGINT, 20.0), (signal.SIGKILL, 5.0)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.communicate(timeout=wait)
            return
        except subprocess.TimeoutExpired:
            continue


def run_trial(
    mission: Callable[[Any], Any],
    settings: SimSettings | None = None,
    output_dir: str | Path | None = None,
    *,
    time_limit: float = 600.0,
    picture: bool = True,
) -> RunRecord:
    """Run `mission(navigator)` against a simulator of its own; its record.

    The callable gets a TurtleBot4Navigator bound to that simulator (rclpy initialised in its domain, shut down
    after). It succeeds when it returns None, True or 0; False or another int fails it (that int is the exit
    code); an exception fails it with the exception as the reason. A callable still running at `time_limit`
    (wall seconds) fails with TIMED_OUT: its goals are canceled, rclpy is shut down under it and the simulator
    stopped.

    Args:
        mission: the mission, taking the navigator.
        settings: the simulator's settings.
        output_dir: the run folder (default: a new temporary folder).
        time_limit: wall seconds the callable may run.
        picture: draw run.png (needs the [render] extra).

    Returns:
        The RunRecord.

    Raises:
        RuntimeError: the simulator did not start, or rclpy is already initialised in this process.
    """
    import rclpy

    from tb4.navigator import TurtleBot4Navigator

    settings = settings or SimSettings()
    folder = Path(output_dir) if output_dir is not None else Path(tempfile.mkdtemp(prefix="tb4-trial-"))
    if rclpy.ok():
        raise RuntimeError("rclpy is already initialised in this process: a trial initialises it in its own domain")
    saved = {key: os.environ.get(key) for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    simulator = Simulator(settings, folder)
    outcome: dict[str, Any] = {}
    started = time.monotonic()
    try:
        simulator.start()
        simulator.activate()
        rclpy.init()
        navigator = TurtleBot4Navigator(namespace=settings.namespace)
        worker = threading.Thread(target=_call, args=(mission, navigator, outcome), name="tb4-trial", daemon=True)
        worker.start()
        worker.join(time_limit)
        if worker.is_alive():
            outcome.update(code=TIMED_OUT, reason=f"timed out: still running after {time_limit:g} s; it was ended")
            navigator.cancelTask()
        navigator.destroyNode()
    finally:
        rclpy.try_shutdown()
        wall_time = time.monotonic() - started
        simulator.stop()
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    code, reason = int(outcome.get("code", 1)), str(outcome.get("reason", "the simulator did not start"))
    _annotate(simulator.record_path, mission, settings, code, reason, wall_time)
    drawn = _draw(folder) if picture else None
    return RunRecord.load(simulator.record_path, exit_code=code, reason=reason, picture=drawn)


def _call(mission: Callable[[Any], Any], navigator: Any, outcome: dict[str, Any]) -> None:
    try:
        value = mission(navigator)
    except BaseException as exc:  # noqa: BLE001 - the mission's failure is the trial's verdict
        last = traceback.format_exception_only(type(exc), exc)[-1].strip()
        outcome.update(code=1, reason=last)
        return
    if value is None or value is True or value == 0:
        outcome.update(code=0, reason="succeeded")
    elif value is False:
        outcome.update(code=1, reason="the mission returned False")
    else:
        code = int(value) if isinstance(value, int) else 1
        outcome.update(code=code, reason=f"the mission returned {value!r}")


def _annotate(
    record_path: Path, mission: Callable[[Any], Any], settings: SimSettings, code: int, reason: str, wall: float
) -> None:
    """How the trial ran and ended, in its record (`run`), as tb4 run writes it for a script."""
    from tb4.ros.run_record import write_run_section

    name = getattr(mission, "__qualname__", type(mission).__name__)
    try:
        bumps = RunRecord.load(record_path).bumps
        write_run_section(
            record_path,
            {
                "mission": {
                    "name": name,
                    "kind": "callable",
                    "target": f"{getattr(mission, '__module__', '?')}.{name}",
                },
                "arguments": [],
                "world": settings.world,
                "seed": settings.seed,
                "rate": settings.rate,
                "battery": settings.battery,
                "exact": settings.exact,
                "localization": settings.localization,
                "robots": settings.robots,
                "namespace": settings.namespace,
                "exit_code": code,
                "reason": reason,
                "wall_time": round(wall, 3),
                "bumps": len(bumps),
            },
        )
    except (OSError, ValueError) as exc:
        raise TrialError(f"the simulator left no run record ({record_path}: {exc})") from None


def _draw(folder: Path) -> Path | None:
    from tb4.extras import MissingExtraError

    try:
        from tb4.runner.picture import render_record

        return render_record(folder)
    except (MissingExtraError, ImportError, OSError, ValueError):
        return None
