"""A sweep's trials on Ray: the same trials and rows as on this machine, spread over a cluster.

When its trials can share simulators (tb4.sweep.reuse.reusable), the sweep runs on Ray actors, one per CPU the
cluster offers: each (`TrialActor`) holds a TrialHost as a local sweep's worker does (a DDS domain claimed on its
node, one simulator reset between trials, the next mission's process started ahead), and is sent trials one or
two at a time (the next waits in the actor, so it never idles for the sweep), those of the world its simulator
was built for first. Otherwise (a fleet, --record, --new-simulators) each trial is a Ray task running `tb4 run`
on its node (`run_trial_row`). A failure's run folder (record, input journal, picture, mission output) comes back
and is written under the sweep's folder, its replay command pointed at it; an actor's simulator logs come back
when it closes. Every node needs this package installed (the same version) in the Python Ray runs its workers with.

An actor or task whose worker dies makes its running trial's row "errored" and the sweep goes on (a dead actor is
replaced, a bounded number of times); what an actor started ends with its process (tb4.processes.end_with_parent).
The `[cluster]` extra installs Ray.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import shlex
import shutil
import socket
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tb4.sweep.matrix import Trial
from tb4.sweep.results import Row

if TYPE_CHECKING:
    from tb4.sweep.runner import Sweep

__all__ = ["run_on_ray", "connect", "RayUnavailable", "ray_trial", "LocalRayHead", "TrialActor", "node_folder_prefix"]

CONNECT_TIMEOUT = 30.0  # wall seconds to reach a cluster
ACTOR_START_TIMEOUT = 120.0  # wall seconds for an actor to start (a new Ray worker and its imports, on a loaded node)
CANCEL_TIMEOUT = 30.0  # wall seconds for the actors' running trials to end once canceled
CLOSE_TIMEOUT = 30.0  # wall seconds for an actor to stop its simulator and mission processes
ACTOR_DEPTH = 2  # trials sent to an actor at once: the one it runs and the next, so it never waits for the sweep
LOG_TAIL = 1 << 20  # bytes of each simulator log an actor sends back (the end, where a crash is)


class RayUnavailable(RuntimeError):
    """Ray is not installed, or the cluster cannot be reached (the message says which and how to fix it)."""


def _keep_ray_on_loopback() -> None:
    """Ray resolves 127.0.0.1 to this machine's network address ("remotely reachable") unless told it is not a
    cluster node: a sweep on one machine keeps every Ray socket on loopback."""
    os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"


def _is_loopback_address(address: str) -> bool:
    from tb4.viewer.access import host_name, is_loopback

    return is_loopback(host_name(address.split("://", 1)[-1]))


def connect(address: str) -> Any:
    """ray.init for a sweep on the cluster at `address` ("HOST:PORT", "auto", "ray://HOST:PORT").

    Raises:
        RayUnavailable: Ray is missing or the address does not answer within CONNECT_TIMEOUT.
    """
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if _is_loopback_address(address):
        _keep_ray_on_loopback()
    try:
        import ray
    except ImportError:
        raise RayUnavailable(
            "Ray is not installed: pip install 'turtlebot4-navigator[cluster]' (or pip install ray)"
        ) from None
    if ray.is_initialized():
        return ray
    _check_reachable(address)
    # ray.init retries an address that stopped answering for ever: bounded here, in a thread it may leave behind
    outcome: dict[str, BaseException | None] = {}

    def init() -> None:
        try:
            ray.init(address=address, logging_level=logging.ERROR, log_to_driver=False)
            outcome["error"] = None
        except BaseException as exc:  # noqa: BLE001 - reported below
            outcome["error"] = exc

    thread = threading.Thread(target=init, name="tb4-ray-connect", daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT)
    if "error" not in outcome:
        raise RayUnavailable(f"the Ray cluster at {address!r} did not answer within {CONNECT_TIMEOUT:g} s")
    if outcome["error"] is not None:
        raise RayUnavailable(f"cannot reach the Ray cluster at {address!r}: {outcome['error']}")
    return ray


def _check_reachable(address: str) -> None:
    """A HOST:PORT that refuses connections fails at once, not after Ray's own retries."""
    if address in ("", "auto") or "://" in address:
        return
    host, _, port = address.rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=5.0):
            return
    except ValueError:
        raise RayUnavailable(f"--ray {address!r}: expected HOST:PORT (the head's GCS port, 6379 by default)") from None
    except OSError as exc:
        raise RayUnavailable(f"cannot reach the Ray cluster at {address!r}: {exc.strerror or exc}") from None


class LocalRayHead:
    """A Ray head of the sweep's own on this machine (`--ray` without an address): `ray start --head --block` bound
    to 127.0.0.1, no dashboard, usage statistics off; stopped by its PID (Ctrl-C ends it and every daemon it
    started), so a sweep leaves no cluster behind."""

    def __init__(self, cpus: int) -> None:
        import subprocess
        import sys

        _keep_ray_on_loopback()
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            self.port = int(probe.getsockname()[1])
        self.address = f"127.0.0.1:{self.port}"
        env = {**os.environ, "RAY_USAGE_STATS_ENABLED": "0"}
        command = [
            sys.executable, "-c", "from ray.scripts.scripts import main; main()", "start", "--head", "--block",
            "--node-ip-address=127.0.0.1", f"--port={self.port}", "--include-dashboard=false",
            f"--num-cpus={cpus}", "--disable-usage-stats",
        ]  # fmt: skip
        self._process = subprocess.Popen(
            command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
        )

    def wait_ready(self, timeout: float = CONNECT_TIMEOUT) -> None:
        """Until the head accepts connections.

        Raises:
            RayUnavailable: it ended, or did not listen within `timeout`.
        """
        from tb4.core.waits import wait_until

        def listening() -> bool:
            if self._process.poll() is not None:
                return True
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1.0):
                    return True
            except OSError:
                return False

        ready = wait_until(listening, timeout, period=0.2)
        if self._process.poll() is not None:
            raise RayUnavailable(f"the local Ray head ended at start (exit code {self._process.returncode})")
        if not ready:
            self.stop()
            raise RayUnavailable(f"the local Ray head did not listen on {self.address} within {timeout:g} s")

    def stop(self) -> None:
        import signal
        import subprocess

        for sig, wait in ((signal.SIGINT, 30.0), (signal.SIGKILL, 10.0)):
            if self._process.poll() is not None:
                return
            try:
                os.killpg(self._process.pid, sig)
                self._process.wait(timeout=wait)
                return
            except ProcessLookupError:
                return
            except subprocess.TimeoutExpired:
                continue


def ray_trial(spec_data: dict[str, Any], trial_data: dict[str, Any]) -> dict[str, Any]:
    """One trial on a Ray worker as `tb4 run`: its row, and a failure's run folder's files as bytes."""
    from tb4.sweep.runner import SweepSpec, run_trial_row

    spec = SweepSpec.from_dict(spec_data)
    trial = Trial(**trial_data)
    folder = Path(tempfile.gettempdir()) / "tb4-sweep-ray"
    row, _ = run_trial_row(spec, trial, folder)
    return {"row": row.__dict__, "files": _run_files(row)}


def _run_files(row: Row) -> dict[str, bytes]:
    """The files of a trial's kept run folder (a failure's record, journal, picture, output, MCAP), by name."""
    if not row.run_dir or not Path(row.run_dir).is_dir():
        return {}
    return {path.name: path.read_bytes() for path in sorted(Path(row.run_dir).iterdir()) if path.is_file()}


def node_folder_prefix(folder: Path) -> str:
    """The name prefix of the temporary folders a sweep's actors run their trials in on their nodes (one per
    actor): it names the sweep, so its simulators and missions can be told by their command lines."""
    digest = hashlib.sha256(str(Path(folder).resolve()).encode()).hexdigest()[:12]
    return f"tb4-sweep-ray-{digest}-"


class TrialActor:
    """A worker of a sweep on a Ray node (run as a Ray actor): a TrialHost in a temporary folder of its own, its
    trials run one after the other. `cancel` and `ready` answer while a trial runs (a concurrency group of
    their own); `close` ends its processes and sends back its simulators' logs.

    Args:
        spec_data: the sweep (SweepSpec.to_dict).
        prefix: its folder's name prefix (node_folder_prefix).
    """

    def __init__(self, spec_data: dict[str, Any], prefix: str) -> None:
        from tb4.sweep.reuse import TrialHost
        from tb4.sweep.runner import SweepSpec

        self._cancel = threading.Event()
        self.folder = Path(tempfile.mkdtemp(prefix=prefix))
        try:
            self.host: Any = TrialHost(SweepSpec.from_dict(spec_data), self.folder, self._cancel)
        except BaseException:
            shutil.rmtree(self.folder, ignore_errors=True)
            raise

    def ready(self) -> str:
        """Its node's name, once it has started."""
        return socket.gethostname()

    def run(self, trial_data: dict[str, Any]) -> dict[str, Any]:
        """One trial: its row, a failure's run folder's files, and whether it was canceled (no row to keep)."""
        if self._cancel.is_set():
            return {"canceled": True}
        row, canceled = self.host.run(Trial(**trial_data))
        files = _run_files(row)
        if row.run_dir:
            shutil.rmtree(row.run_dir, ignore_errors=True)  # sent back: the sweep's folder keeps it
        return {"row": row.__dict__, "files": files, "canceled": canceled}

    def cancel(self) -> None:
        """End the running trial (Ctrl-C on the sweep); the trials sent after it do not run."""
        self._cancel.set()

    def close(self) -> dict[str, bytes]:
        """End its simulator and mission processes, give its domain back, remove its folder; its simulators'
        logs (their last LOG_TAIL bytes), by name."""
        self._cancel.set()
        self.host.close()
        logs: dict[str, bytes] = {}
        for path in sorted((self.folder / "simulators").glob("*.log")):
            with path.open("rb") as stream:
                stream.seek(max(0, path.stat().st_size - LOG_TAIL))
                logs[path.name] = stream.read()
        shutil.rmtree(self.folder, ignore_errors=True)
        return logs


def run_on_ray(sweep: Sweep, on_row: Callable[[Row], None] | None) -> None:
    """Run `sweep.pending` on Ray (on actors when its trials can share simulators, else as tasks; one CPU each),
    keeping each row as its trial ends, until done or canceled; on a Ray head of its own when `sweep.ray_address`
    is empty.

    Raises:
        RayUnavailable: Ray is missing or the cluster does not answer.
    """
    head = LocalRayHead(sweep.workers) if not sweep.ray_address else None
    try:
        if head is not None:
            head.wait_ready()
        ray = connect(head.address if head is not None else str(sweep.ray_address))
        try:
            from tb4.sweep.reuse import reusable

            if reusable(sweep.spec):
                _ActorPool(ray, sweep, on_row).run()
            else:
                _run_tasks(ray, sweep, on_row)
        finally:
            ray.shutdown()
    finally:
        if head is not None:
            head.stop()


def _run_tasks(ray: Any, sweep: Sweep, on_row: Callable[[Row], None] | None) -> None:
    from tb4.sweep.runner import errored_row

    remote = ray.remote(num_cpus=1, max_retries=0)(ray_trial)
    spec_data = sweep.spec.to_dict()
    queue = list(sweep.pending)
    in_flight: dict[Any, Trial] = {}
    limit = max(1, int(ray.cluster_resources().get("CPU", 1)))
    while queue or in_flight:
        while queue and len(in_flight) < limit and not sweep.canceled:
            trial = queue.pop(0)
            in_flight[remote.remote(spec_data, trial.as_dict())] = trial
        if sweep.canceled:
            for ref in in_flight:
                ray.cancel(ref, force=True)  # the worker's process group ends with it (end_with_parent)
            return
        if not in_flight:
            break
        ready, _ = ray.wait(list(in_flight), num_returns=1, timeout=0.5)
        for ref in ready:
            trial = in_flight.pop(ref)
            try:
                result = ray.get(ref)
            except Exception as exc:  # noqa: BLE001 - a task that died (worker crash, node lost): errored, go on
                sweep.keep(errored_row(sweep.spec, trial, f"the Ray task failed: {type(exc).__name__}: {exc}"), on_row)
                continue
            sweep.keep(_localize(sweep.folder, Row.from_dict(result["row"]), result["files"]), on_row)


def _localize(folder: Path, row: Row, files: dict[str, bytes]) -> Row:
    """A failure's run folder written under this sweep's folder, and the row pointed at it (its replay command too:
    the journal beside the record came with it)."""
    if not files:
        return row
    target = folder / "runs" / f"{row.index:06d}-{row.node}"
    target.mkdir(parents=True, exist_ok=True)
    for name, data in files.items():
        (target / Path(name).name).write_bytes(data)
    old_record = row.record
    for name in ("record", "picture", "mcap"):
        path = getattr(row, name)
        if path and (target / Path(path).name).is_file():
            setattr(row, name, str(target / Path(path).name))
    if old_record and row.replay == shlex.join(["tb4", "replay", old_record]):
        row.replay = shlex.join(["tb4", "replay", row.record])
    row.run_dir = str(target)
    return row


@dataclass
class _Slot:
    """One actor of the pool: what it was sent (in order: it runs them so), the simulator build of the last."""

    actor: Any
    number: int
    starting: Any = None  # its `ready` call until it has answered
    started: float = field(default_factory=time.monotonic)
    build: Any = None
    running: dict[Any, Trial] = field(default_factory=dict)


class _ActorPool:
    """A sweep's trials on TrialActors, one per CPU of the cluster (see the module)."""

    def __init__(self, ray: Any, sweep: Sweep, on_row: Callable[[Row], None] | None) -> None:
        self.ray = ray
        self.sweep = sweep
        self.on_row = on_row
        self.spec_data = sweep.spec.to_dict()
        self.prefix = node_folder_prefix(sweep.folder)
        self.remote = ray.remote(num_cpus=1, max_restarts=0, max_task_retries=0, concurrency_groups={"control": 1})(
            TrialActor
        )
        self.queue = list(sweep.pending)
        self.slots: list[_Slot] = []
        self.count = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self.replacements = self.count  # dead actors replaced at most this many times in all
        self.numbers = 0
        self.last_error = ""

    def run(self) -> None:
        """Until every trial has its row or the sweep is canceled; the actors closed in any case.

        Raises:
            RayUnavailable: every actor died or could not start (the rows kept so far stay; --resume goes on).
        """
        try:
            for _ in range(self.count):
                self._start_actor()
            self._loop()
        finally:
            self._close()

    def _start_actor(self) -> None:
        self.numbers += 1
        actor = self.remote.remote(self.spec_data, self.prefix)
        starting = actor.ready.options(concurrency_group="control").remote()
        self.slots.append(_Slot(actor, self.numbers, starting=starting))

    def _loop(self) -> None:
        from tb4.sweep.reuse import SimulatorBuild

        while not self.sweep.canceled:
            for slot in self.slots:
                while slot.starting is None and (trial := self._next_for(slot)) is not None:
                    slot.running[slot.actor.run.remote(trial.as_dict())] = trial
                    slot.build = SimulatorBuild.of(trial)
            waiting = [ref for slot in self.slots for ref in (slot.running or [slot.starting]) if ref is not None]
            if not waiting:
                if not self.queue:
                    return
                raise RayUnavailable(f"no Ray worker left to run the sweep's trials ({self.last_error})")
            ready, _ = self.ray.wait(waiting, num_returns=1, timeout=0.5)
            for ref in ready:
                self._collect(ref)
            self._check_starts()
        self._cancel_running()

    def _next_for(self, slot: _Slot) -> Trial | None:
        """The next trial for `slot`: one of its simulator's build, else (when it runs nothing) the first waiting."""
        from tb4.sweep.reuse import SimulatorBuild

        if len(slot.running) >= ACTOR_DEPTH or not self.queue:
            return None
        if slot.build is not None:
            for i, trial in enumerate(self.queue):
                if SimulatorBuild.of(trial) == slot.build:
                    return self.queue.pop(i)
        return self.queue.pop(0) if not slot.running else None

    def _slot_of(self, ref: Any) -> _Slot | None:
        return next((slot for slot in self.slots if ref in slot.running or _same(ref, slot.starting)), None)

    def _collect(self, ref: Any) -> None:
        slot = self._slot_of(ref)
        if slot is None:
            return
        if _same(ref, slot.starting):
            try:
                self.ray.get(ref)
                slot.starting = None
            except Exception as exc:  # noqa: BLE001 - an actor that cannot start: dropped, the others go on
                self._drop(slot, f"a Ray worker could not start: {_brief(exc)}", replace=False)
            return
        from ray.exceptions import RayActorError

        try:
            result = self.ray.get(ref)
        except RayActorError as exc:
            self._actor_died(slot, exc)
            return
        except Exception as exc:  # noqa: BLE001 - the trial raised on its worker: errored, the actor goes on
            trial = slot.running.pop(ref)
            self._keep_errored(trial, f"the Ray worker failed: {_brief(exc)}")
            return
        slot.running.pop(ref)
        self._keep(result)

    def _keep(self, result: dict[str, Any]) -> None:
        if not result.get("canceled"):
            self.sweep.keep(_localize(self.sweep.folder, Row.from_dict(result["row"]), result["files"]), self.on_row)

    def _keep_errored(self, trial: Trial, reason: str) -> None:
        from tb4.sweep.runner import errored_row

        self.sweep.keep(errored_row(self.sweep.spec, trial, reason), self.on_row)

    def _actor_died(self, slot: _Slot, exc: BaseException) -> None:
        """The trial it was running errored, those sent after it back in the queue; the actor replaced."""
        reason = f"the Ray worker running it died: {_brief(exc)}"
        sent = list(slot.running.items())
        slot.running.clear()
        for i, (ref, trial) in enumerate(sent):  # it ran them in this order: the first without a result was running
            try:
                ready, _ = self.ray.wait([ref], num_returns=1, timeout=5.0)
                result = self.ray.get(ready[0]) if ready else None
            except Exception:  # noqa: BLE001 - no result: it died running this one
                result = None
            if result is None:
                self._keep_errored(trial, reason)
                self.queue[:0] = [later for _, later in sent[i + 1 :]]  # never started: they run elsewhere
                break
            self._keep(result)  # it ended before the actor died
        self._drop(slot, reason, replace=True)

    def _drop(self, slot: _Slot, reason: str, replace: bool) -> None:
        self.last_error = reason
        self.slots.remove(slot)
        self.queue[:0] = list(slot.running.values())
        slot.running.clear()
        with contextlib.suppress(Exception):
            self.ray.kill(slot.actor, no_restart=True)
        if replace and self.replacements > 0:
            self.replacements -= 1
            self._start_actor()

    def _check_starts(self) -> None:
        for slot in list(self.slots):
            if slot.starting is not None and time.monotonic() - slot.started > ACTOR_START_TIMEOUT:
                self._drop(slot, f"a Ray worker did not start within {ACTOR_START_TIMEOUT:g} s", replace=False)

    def _cancel_running(self) -> None:
        """Ctrl-C: each actor ends its running trial; a trial that ended first keeps its row."""
        for slot in self.slots:
            with contextlib.suppress(Exception):
                slot.actor.cancel.options(concurrency_group="control").remote()
        deadline = time.monotonic() + CANCEL_TIMEOUT
        for slot in self.slots:
            for ref in list(slot.running):
                ready, _ = self.ray.wait([ref], num_returns=1, timeout=max(0.0, deadline - time.monotonic()))
                with contextlib.suppress(Exception):
                    if ready:
                        self._keep(self.ray.get(ref))
            slot.running.clear()

    def _close(self) -> None:
        """Every actor closed (its processes ended, its logs written under the sweep's folder), then killed: one
        that does not close in time takes its processes with it (end_with_parent). The folders of the actors that
        died are removed on this node."""
        closing: dict[Any, _Slot] = {}
        for slot in self.slots:
            with contextlib.suppress(Exception):
                slot.actor.cancel.options(concurrency_group="control").remote()
                closing[slot.actor.close.remote()] = slot
        if closing:
            self.ray.wait(list(closing), num_returns=len(closing), timeout=CLOSE_TIMEOUT)
        logs = self.sweep.folder / "runs" / "simulators"
        for ref, slot in closing.items():
            with contextlib.suppress(Exception):
                ready, _ = self.ray.wait([ref], num_returns=1, timeout=0)
                for name, data in (self.ray.get(ready[0]) if ready else {}).items():
                    logs.mkdir(parents=True, exist_ok=True)
                    (logs / f"actor{slot.number}-{Path(name).name}").write_bytes(data)
        for slot in self.slots:
            with contextlib.suppress(Exception):
                self.ray.kill(slot.actor, no_restart=True)
        self.slots.clear()
        # an actor that died left its folder; those on this node go now (another node's stay in its temp folder)
        for left in Path(tempfile.gettempdir()).glob(f"{self.prefix}*"):
            shutil.rmtree(left, ignore_errors=True)


def _same(ref: Any, other: Any) -> bool:
    return other is not None and ref == other


def _brief(exc: BaseException) -> str:
    """An exception in one line (Ray's carry their whole traceback)."""
    lines = [line for line in str(exc).splitlines() if line.strip()]
    text = lines[0] if lines else ""
    return f"{type(exc).__name__}: {text}"[:300]
