"""Test harness: a ROS_DOMAIN_ID of our own per session, loopback-only DDS, real processes stopped by PID.

Core tests (marker `core`) never touch DDS. Tests under tests/ros and tests/e2e (and tests/cross, the cross-distro
stage) get the `dds` / `e2e` marker from their folder and share the session's domain.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tb4.processes import (
    ManagedProcess,
    claim_domain_id,
    clean_shm_after_exit,
    remove_stale_shm,
    ros_environment,
    shm_snapshot,
    tb4_command,
)
from tb4.rosenv import apply_safe_ros_defaults


def pytest_configure(config: pytest.Config) -> None:
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    apply_safe_ros_defaults()  # and the other defaults of our processes, for every process a test starts
    # a process that dies of a signal (a crash in C code) leaves a Python traceback in its log, not silence
    os.environ.setdefault("PYTHONFAULTHANDLER", "1")
    # each pytest-xdist worker is a session of its own: it claims a domain of its own, as its simulators' /clock
    # and topic names would otherwise meet another worker's
    if "TB4_TEST_DOMAIN_ID" not in os.environ or "PYTEST_XDIST_WORKER" in os.environ:
        os.environ["TB4_TEST_DOMAIN_ID"] = str(claim_domain_id())
    os.environ["ROS_DOMAIN_ID"] = os.environ["TB4_TEST_DOMAIN_ID"]
    config._tb4_shm_before = shm_snapshot()  # type: ignore[attr-defined]
    # A test run started as a background job of a script (`make test &` in a non-interactive shell; a CI job may
    # be one) inherits SIGINT ignored, and so would every program a test starts: one that does not restore SIGINT itself
    # (an upstream example script, a plain `python -c`) would then sit out stop()'s whole grace period before
    # SIGTERM. The tests run as from a terminal instead, where Ctrl-C (SIGINT) interrupts.
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_unconfigure(config: pytest.Config) -> None:
    before = getattr(config, "_tb4_shm_before", None)
    if before is not None:
        remove_stale_shm(before)
        # This process may itself hold DDS segments until it exits: clean those up right after.
        clean_shm_after_exit(before)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        parts = Path(str(item.fspath)).parts
        if "ros" in parts:
            item.add_marker(pytest.mark.dds)
        elif "e2e" in parts or "cross" in parts:
            item.add_marker(pytest.mark.e2e)
        elif "core" in parts:
            item.add_marker(pytest.mark.core)
    # The DDS and end-to-end tests first, the core tests last: a DDS test waits part of its time (simulated time,
    # discovery, a process starting) and lasts up to half a minute, while the core tests are short and keep every
    # core busy. Run last, they fill the end of the run that the long tests would otherwise leave to one or two
    # workers (pytest-xdist hands out tests in this order as workers free up).
    items.sort(key=lambda item: item.get_closest_marker("core") is not None)


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    return int(os.environ["ROS_DOMAIN_ID"])


@pytest.fixture
def ros_env(ros_domain_id: int) -> dict[str, str]:
    """Environment for child processes: this session's domain, loopback only; faulthandler on, so that a child that
    hangs can be made to say where (ManagedProcess.abort_showing_stacks)."""
    return {**ros_environment(ros_domain_id), "PYTHONFAULTHANDLER": "1"}


#: the processes a test started, so that a failed test's report carries what they printed
PROCESSES = pytest.StashKey[list[tuple[str, ManagedProcess]]]()
OUTPUT_TAIL = 6000  # characters of each process's output in a failed test's report


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    if report.when == "call" and report.failed:
        for name, proc in item.stash.get(PROCESSES, []):
            report.sections.append((f"output of process {name}", proc.output()[-OUTPUT_TAIL:]))


@pytest.fixture
def start_process(
    ros_env: dict[str, str], tmp_path: Path, request: pytest.FixtureRequest
) -> Iterator[Callable[..., ManagedProcess]]:
    """Start real processes; each is stopped by PID at teardown and its stale shared memory removed. A failed
    test's report shows the end of what each printed."""
    started: list[ManagedProcess] = []
    named = request.node.stash.setdefault(PROCESSES, [])
    before = shm_snapshot()

    def _start(args: list[str], name: str = "proc", **kwargs) -> ManagedProcess:
        kwargs.setdefault("env", ros_env)
        proc = ManagedProcess(args, log_path=tmp_path / f"{name}-{len(started)}.log", **kwargs)
        started.append(proc)
        named.append((f"{name}-{len(started) - 1}", proc))
        return proc

    yield _start
    for proc in reversed(started):
        proc.stop()
    remove_stale_shm(before)


@pytest.fixture
def start_simulator(start_process: Callable[..., ManagedProcess]) -> Callable[..., ManagedProcess]:
    """Start `tb4 sim` with the given options and wait until it is serving (stopped by PID at teardown).

    With `--rate max`, add `--hold` where the test's first act is a command (an action goal, a Create 3 service):
    until then the simulator runs at real time instead of burning a core on the dock while the test's clients
    start and discover it."""

    def _start(*options: str, name: str = "sim") -> ManagedProcess:
        from tb4.ros.simulator import READY_LINE  # here: the core tests never import ROS

        proc = start_process(tb4_command("sim", *options), name=name)
        if not proc.wait_for_output(READY_LINE, timeout=60):
            raise AssertionError(f"simulator did not start:\n{proc.output()}")
        return proc

    return _start
