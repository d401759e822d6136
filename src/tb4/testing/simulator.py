"""A simulator of a test's own: `tb4 sim` in a DDS domain no other run on the machine holds, on loopback, stopped
by PID, its shared-memory files removed. What a launch file does for a ROS test, without one.

Readiness is the line `tb4 sim ready: world=... seed=...` on the simulator's standard output (READY_LINE), printed
once every interface is served; a program that starts `tb4 sim` itself can wait for the same line.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

from tb4.processes import (
    READY_LINE,
    ManagedProcess,
    claim_domain_id,
    release_domain_id,
    remove_stale_shm,
    ros_environment,
    shm_snapshot,
    tb4_command,
)
from tb4.testing.record import RunRecord

__all__ = ["SimSettings", "Simulator", "READY_LINE", "START_TIMEOUT"]

START_TIMEOUT = 60.0  # wall seconds for a simulator to be ready on a loaded machine
STOP_TIMEOUT = 20.0  # wall seconds for it to write its record and end after Ctrl-C


@dataclass(frozen=True)
class SimSettings:
    """How a test's simulator runs: the `tb4 sim` options of the same names.

    Attributes:
        world: a world name or world file.
        seed: the random seed (noise, obstacles).
        rate: "max", or N times real time.
        battery: the start battery level 0..1 (None: the world's).
        exact: no odometry drift and no lidar noise.
        localization: "amcl", "truth" or "odometry".
        robots: a fleet of N robots (robot1..robotN); 0 for one.
        namespace: the one robot's namespace.
    """

    world: str = "warehouse"
    seed: int = 0
    rate: str = "max"
    battery: float | None = None
    exact: bool = False
    localization: str = "amcl"
    robots: int = 0
    namespace: str = ""
    extra: tuple[str, ...] = field(default=())

    def sim_arguments(self) -> list[str]:
        """The options of `tb4 sim` (and `tb4 run`) that make these settings."""
        args = ["--world", self.world, "--seed", str(self.seed), "--rate", str(self.rate)]
        args += ["--localization", self.localization]
        if self.battery is not None:
            args += ["--battery", str(self.battery)]
        if self.exact:
            args.append("--exact")
        if self.namespace:
            args += ["--namespace", self.namespace]
        return args + list(self.extra)


class Simulator:
    """`tb4 sim` with `settings` in a domain of its own; a context manager.

    Attributes:
        domain_id: its ROS_DOMAIN_ID (clients must use it: `env` for processes, `Simulator.activate()` here).
        env: an environment for child processes that talk to it.
        record_path: where it writes its run record when it stops.
        log_path: what it printed.
    """

    def __init__(self, settings: SimSettings | None = None, folder: Path | None = None, hold: bool = True) -> None:
        self.settings = settings or SimSettings()
        self.folder = Path(folder) if folder is not None else Path(tempfile.mkdtemp(prefix="tb4-sim-"))
        self.folder.mkdir(parents=True, exist_ok=True)
        self.record_path = self.folder / "run.json"
        self.log_path = self.folder / "sim.log"
        self.hold = hold
        self.domain_id = -1
        self.env: dict[str, str] = {}
        self.process: ManagedProcess | None = None
        self._shm_before: set[str] = set()

    def start(self, timeout: float = START_TIMEOUT) -> Simulator:
        """Start it and wait until it is ready.

        Raises:
            RuntimeError: it did not become ready within `timeout` (the message ends with what it printed).
        """
        self._shm_before = shm_snapshot()
        self.domain_id = claim_domain_id()
        self.env = ros_environment(self.domain_id)
        args = tb4_command("sim", *self.settings.sim_arguments(), "--record-run", str(self.record_path))
        if self.settings.robots:
            args += ["--robots", str(self.settings.robots)]
        if self.hold:
            args.append("--hold")  # real time until the first command: a test's set-up costs no sim time
        self.process = ManagedProcess(args, env=self.env, log_path=self.log_path)
        if not self.process.wait_for_output(READY_LINE, timeout):
            output = self.process.output()[-2000:]
            self.stop()
            raise RuntimeError(f"tb4 sim was not ready within {timeout:g} s; it printed:\n{output}")
        return self

    def stop(self, timeout: float = STOP_TIMEOUT) -> int | None:
        """Stop it by PID (Ctrl-C first: it writes its record), give its domain back, remove its DDS files."""
        code = None
        if self.process is not None:
            code = self.process.stop(timeout=timeout)
            self.process = None
        if self.domain_id >= 0:
            release_domain_id(self.domain_id)
            self.domain_id = -1
        remove_stale_shm(self._shm_before)
        return code

    def finish(self) -> RunRecord:
        """Stop it and read the run it served (its record is written as it stops).

        Raises:
            FileNotFoundError: it wrote no record (it was killed, or never started).
        """
        self.stop()
        return RunRecord.load(self.record_path)

    def activate(self) -> None:
        """Point this process's ROS clients at this simulator (its domain, loopback), before rclpy.init."""
        os.environ["ROS_DOMAIN_ID"] = str(self.domain_id)
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

    def output(self) -> str:
        return self.log_path.read_text(errors="replace") if self.log_path.exists() else ""

    def __enter__(self) -> Simulator:
        return self.start()

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.stop()
