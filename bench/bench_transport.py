"""Benchmark: what carrying DDS data over loopback UDP costs beside Fast DDS's shared memory.

Under loopback discovery our processes take their DDS data over UDP on 127.0.0.1 (tb4/ros/fastdds_loopback.xml
and the simulator's *_loopback.xml profiles), not over the shared memory rmw_fastrtps turns on under LOCALHOST,
whose one-second health check can lose one direction of a busy pair of processes' data for good. Two cases in the
same run, each with processes and a ROS domain of their own: ours (loopback UDP), and the baseline, shared memory:
the simulator with its profile as it was before (no loopback locator) and the client with an empty profile file,
that is Fast DDS's transports as rmw_fastrtps sets them under LOCALHOST.

Figures per case, from a client process (a raw rclpy node, as bench_system's) and a real simulator process: the
simulator's real-time factor with a still robot publishing over DDS and across-the-warehouse navigation (the
measurements of bench_system), a service's round trip (amcl/get_state, median and 99th percentile of CALLS calls,
the simulator paced at real time) and the time a new subscriber takes to receive the latched map (1.6 MB).

    python bench/bench_transport.py [--quick]

Loopback only, each case in a ROS domain of its own; every process it starts is stopped by PID.
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "src"))

from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402
from tb4.rosenv import (  # noqa: E402
    FASTDDS_PROFILE_VARIABLES,
    apply_safe_ros_defaults,
    installed_middleware,
    simulator_dds_profile,
)

__all__ = ["run"]

CALLS = 500
CASE_LIMIT = 600.0  # wall s a case's client process may take before it is stopped
RESULT = "RESULT "

EMPTY_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <participant profile_name="bench_fast_dds_defaults" is_default_profile="true">
      <rtps/>
    </participant>
  </profiles>
</dds>
"""


def _latency_figures(calls: int) -> dict[str, float]:
    """(In the client process.) The latched map's delivery to a new subscriber and `calls` get_state round trips, s."""
    from lifecycle_msgs.srv import GetState
    from nav_msgs.msg import OccupancyGrid

    from bench_system import _Client
    from tb4.core.waits import wait_for_future, wait_until
    from tb4.ros.qos import LATCHED

    sim = ManagedProcess(
        tb4_command("sim", "--rate", "1"), env=_simulator_env(), log_path=Path(tempfile.mkstemp(suffix=".log")[1])
    )
    client = None
    try:
        if not sim.wait_for_output("tb4 sim ready", 60):
            raise RuntimeError(sim.output())
        client = _Client()
        maps: list[float] = []
        start = time.monotonic()
        client.node.create_subscription(OccupancyGrid, "map", lambda _msg: maps.append(time.monotonic()), LATCHED)
        wait_until(lambda: bool(maps), 60, "the latched map")
        map_seconds = maps[0] - start
        service = client.node.create_client(GetState, "amcl/get_state")
        if not service.wait_for_service(timeout_sec=20):
            raise RuntimeError("no amcl/get_state")
        round_trips = []
        for _ in range(calls):
            sent = time.monotonic()
            wait_for_future(service.call_async(GetState.Request()), 10, "amcl/get_state reply")
            round_trips.append(time.monotonic() - sent)
        round_trips.sort()
        return {
            "map": map_seconds,
            "call_median": statistics.median(round_trips),
            "call_p99": round_trips[min(len(round_trips) - 1, int(0.99 * len(round_trips)))],
        }
    finally:
        if client is not None:
            client.close()
        sim.stop()


def _simulator_env() -> dict[str, str]:
    """(In the client process.) The simulator's environment: the client's, with the baseline's simulator profile in
    the variable Fast DDS reads when the case names one."""
    env = dict(os.environ)
    if "BENCH_SIM_PROFILE" in env:
        env[simulator_dds_profile(installed_middleware().fast_dds, loopback=False)[0]] = env.pop("BENCH_SIM_PROFILE")
    return env


def case_main(calls: int) -> None:
    """(The client process of one case.) Print the case's figures as one RESULT line of JSON."""
    from bench_system import _dds_figures

    still_rtf, nav_sim, nav_wall = _dds_figures(_simulator_env())
    figures = {"still_rtf": still_rtf, "nav_rtf": nav_sim / nav_wall, **_latency_figures(calls)}
    print(RESULT + json.dumps(figures), flush=True)


def _case_env(shared_memory: bool, folder: Path) -> dict[str, str]:
    """A case's environment, in a domain of its own: ours (the loopback profile, as every tb4 process sets it), or
    Fast DDS's transports under LOCALHOST for the client and the simulator's profile without its loopback locator."""
    env = {k: v for k, v in ros_environment(claim_domain_id()).items() if k not in FASTDDS_PROFILE_VARIABLES}
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if shared_memory:
        variable, simulator_profile = simulator_dds_profile(installed_middleware().fast_dds, loopback=False)
        empty = folder / "fast_dds_defaults.xml"
        empty.write_text(EMPTY_PROFILE)
        copied = folder / simulator_profile.name  # a file of the user's own to tb4: left as it is
        copied.write_text(simulator_profile.read_text())
        env[variable] = str(empty)
        env["BENCH_SIM_PROFILE"] = str(copied)
    apply_safe_ros_defaults(env)  # the other defaults (NumPy's BLAS threads) alike in both cases
    return env


def _run_case(shared_memory: bool, calls: int) -> dict[str, float]:
    folder = Path(tempfile.mkdtemp(prefix="bench-transport-"))
    proc = subprocess.run(
        [sys.executable, __file__, "--case", "--calls", str(calls)],
        env=_case_env(shared_memory, folder),
        capture_output=True,
        text=True,
        timeout=CASE_LIMIT,
    )
    for line in proc.stdout.splitlines():
        if line.startswith(RESULT):
            return json.loads(line[len(RESULT) :])
    case = "shared memory" if shared_memory else "loopback UDP"
    raise RuntimeError(f"case {case} gave no result: {proc.stdout[-800:]} {proc.stderr[-800:]}")


def run(quick: bool = False) -> list[dict]:
    calls = 100 if quick else CALLS
    ours = _run_case(False, calls)
    shm = _run_case(True, calls)
    figures = (  # (name, key, unit, scale, higher is better)
        ("simulator RTF, still robot publishing over DDS", "still_rtf", "x", 1.0, True),
        ("navigation across the warehouse over DDS (RTF)", "nav_rtf", "x", 1.0, True),
        (f"amcl/get_state round trip, median of {calls}", "call_median", "ms", 1e3, False),
        (f"amcl/get_state round trip, 99th percentile of {calls}", "call_p99", "ms", 1e3, False),
        ("latched map (1.6 MB) to a new subscriber", "map", "s", 1.0, False),
    )
    return [
        {
            "name": f"{name}: loopback UDP",
            "ours": ours[key] * scale,
            "baseline": shm[key] * scale,
            "baseline_name": "the same over shared memory (Fast DDS's default under LOCALHOST)",
            "unit": unit,
            "ratio": ours[key] / shm[key] if higher else shm[key] / ours[key],
            "goal": ">= 0.75x (no cost beyond the run-to-run noise)",
        }
        for name, key, unit, scale, higher in figures
    ]


if __name__ == "__main__":
    if "--case" in sys.argv:
        case_main(int(sys.argv[sys.argv.index("--calls") + 1]))
    else:
        for row in run(quick="--quick" in sys.argv):
            print(row)
