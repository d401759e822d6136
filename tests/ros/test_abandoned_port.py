"""A process killed between creating a Fast DDS port segment and sizing it leaves the segment empty, and every
participant that opens it afterwards waits in its creation forever (rclpy.create_node never returns, SIGTERM is not
even handled). tb4's processes free such a port before and while they make their first node
(tb4.processes.abandoned_ports_watched), here in a domain of this test's own.

That a plain rclpy node waits forever there is not tested here: any tb4 process starting meanwhile on the machine
(another worker's) frees the port, by design. By hand, with nothing else running, a plain node on such a port was
still waiting when `timeout` killed it (SIGTERM unheard, SIGKILL after), on Kilted's and Jazzy's Fast DDS alike."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from tb4.processes import (
    ABANDONED_PORT_AGE,
    SHM_DIR,
    ManagedProcess,
    claim_domain_id,
    remove_stale_shm,
    ros_environment,
    shm_snapshot,
)

OURS_LIMIT = 30.0  # s for tb4's node to come up through the abandoned port


@pytest.fixture
def abandoned_domain() -> Iterator[int]:
    """A domain whose first participant's port segment (its user unicast port) is empty and older than
    ABANDONED_PORT_AGE: Fast DDS 3 (Kilted) and 2.14 (Jazzy) name it differently, so both are made."""
    domain = claim_domain_id(first=102, last=140)
    before = shm_snapshot()
    port = 7400 + 250 * domain + 11  # RTPS user unicast port of participant 0 (d3 = 11)
    made = [SHM_DIR / f"{prefix}_port{port}" for prefix in ("fastdds", "fastrtps")]
    # held open, as the participants that wait on such a port hold it: other tests' clean-up of unused leftovers
    # (remove_stale_shm) must not take it away meanwhile
    held = [os.open(path, os.O_RDONLY | os.O_CREAT) for path in made]
    try:
        time.sleep(ABANDONED_PORT_AGE + 0.5)
        yield domain
    finally:
        for handle in held:
            os.close(handle)
        for path in made:
            path.unlink(missing_ok=True)
        remove_stale_shm(before)


def _comes_up(code: str, domain: int, patience: float) -> bool:
    process = ManagedProcess([sys.executable, "-c", code], env=ros_environment(domain))
    try:
        process.popen.wait(timeout=patience)
    except subprocess.TimeoutExpired:
        return False
    finally:
        process.stop(timeout=0.5)  # a wedged one handles no signal: SIGKILL ends it
    return process.popen.returncode == 0


def test_tb4s_node_frees_the_abandoned_port_and_comes_up(abandoned_domain) -> None:
    ours = "from tb4.ros.background import BackgroundNode; BackgroundNode('rescued').close()"
    assert _comes_up(ours, abandoned_domain, OURS_LIMIT), "tb4's node did not come up through an abandoned port"
