"""A sweep's trials as Ray tasks: the same trials and rows as on this machine, spread over a cluster.

Each task runs one trial on its node exactly as a local sweep does (`run_trial_row`: `tb4 run` in a DDS domain
claimed on that node, so trials sharing a node never hear each other) and returns its row; a failure also returns
its run record and picture, which are written under the sweep's folder here (the node's copy stays where it ran).
Every node needs this package installed (the same version) in the Python that Ray runs its workers with.

The `[cluster]` extra installs Ray. A task whose worker dies makes its trial's row "errored"; the sweep goes on.
"""

from __future__ import annotations

import logging
import os
import socket
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tb4.sweep.matrix import Trial
from tb4.sweep.results import Row

if TYPE_CHECKING:
    from tb4.sweep.runner import Sweep

__all__ = ["run_on_ray", "connect", "RayUnavailable", "ray_trial", "LocalRayHead"]

CONNECT_TIMEOUT = 30.0  # wall seconds to reach a cluster


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
    """One trial on a Ray worker: its row, and a failure's record and picture as bytes."""
    from tb4.sweep.runner import SweepSpec, run_trial_row

    spec = SweepSpec.from_dict(spec_data)
    trial = Trial(**trial_data)
    folder = Path(tempfile.gettempdir()) / "tb4-sweep-ray"
    row, _ = run_trial_row(spec, trial, folder)
    files: dict[str, bytes] = {}
    for name in ("record", "picture", "mcap"):
        path = getattr(row, name)
        if path and Path(path).is_file():
            files[name] = Path(path).read_bytes()
    return {"row": row.__dict__, "files": files}


def run_on_ray(sweep: Sweep, on_row: Callable[[Row], None] | None) -> None:
    """Run `sweep.pending` as Ray tasks (one CPU each), keeping each row as its task ends, until done or canceled;
    on a Ray head of its own when `sweep.ray_address` is empty.

    Raises:
        RayUnavailable: Ray is missing or the cluster does not answer.
    """
    head = LocalRayHead(sweep.workers) if not sweep.ray_address else None
    try:
        if head is not None:
            head.wait_ready()
        ray = connect(head.address if head is not None else str(sweep.ray_address))
        try:
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
    """A failure's files written under this sweep's folder, and the row pointed at them."""
    if not files:
        return row
    target = folder / "runs" / f"{row.index:06d}-{row.node}"
    target.mkdir(parents=True, exist_ok=True)
    names = {"record": "run.json", "picture": "run.png", "mcap": "run.mcap"}
    for name, data in files.items():
        path = target / names[name]
        path.write_bytes(data)
        setattr(row, name, str(path))
    row.run_dir = str(target)
    return row
