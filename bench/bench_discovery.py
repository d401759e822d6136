"""Benchmark: does a script started beside a running simulator find it, every time? Fresh processes, under load.

Each script is a new process, as a user's mission is: a TurtleBot4Navigator, setInitialPose at a random pose near
the dock, then waitUntilNav2Active, which needs the simulator's amcl and bt_navigator get_state services and an
amcl_pose at the pose set (limits of 20 s each). A script that ends without "Nav2 is ready" failed, and says why.
PARALLEL scripts run at a time, one after another, beside BUSY processes that spin a core each
(`while True: pass`), as the test suite's stress runs have them.

Two cases, in the same run, each with a simulator of its own: the simulator's DDS profile as shipped for loopback
discovery (tb4/ros/fastdds_simulator_loopback.xml: Fast DDS type propagation off), and the same profile with type
propagation left at Fast DDS's default (on), the baseline; the scripts have the simulator's profile too. With it
on, Fast DDS 3 makes a remote endpoint known only after the type it announces is known locally (asking the
simulator for it otherwise), and a script now and then never saw some of the simulator's services.

    python bench/bench_discovery.py [--quick] [--scripts N] [--parallel N] [--busy N]

Fast DDS 3 (Kilted) only: Fast DDS 2 has no such wait, and its profile no such property. Loopback only, in a
ROS_DOMAIN_ID of its own per case (150-230); every process it starts is stopped by PID.
"""

from __future__ import annotations

import argparse
import os
import random
import re
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402
from tb4.rosenv import SIMULATOR_LOOPBACK_DDS_PROFILE, installed_middleware  # noqa: E402

__all__ = ["run", "script"]

NAMESPACE = "discovery"
SCRIPT_LIMIT = 60.0  # wall s a script may take before it is stopped (its own limits end it well before)
READY = "Nav2 is ready"


def script(namespace: str) -> int:
    """One fresh script's run (in its own process); prints "RESULT ok" or "RESULT FAIL <why>"."""
    import rclpy

    from tb4.navigator import NavigatorTimeout, TurtleBot4Navigator
    from tb4.navigator.timeouts import DEFAULT_TIMEOUTS

    rclpy.init()
    nav = TurtleBot4Navigator(namespace=namespace, timeouts=DEFAULT_TIMEOUTS.with_(lifecycle=20.0, localization=20.0))
    try:
        pose = nav.getPoseStamped([round(random.uniform(-2.0, -0.5), 2), 0.0], random.choice([0, 90, 180, 270]))
        nav.setInitialPose(pose)
        nav.waitUntilNav2Active()
        print("RESULT ok", flush=True)
        return 0
    except NavigatorTimeout as exc:
        print(f"RESULT FAIL {exc}", flush=True)
        return 1
    finally:
        nav.destroyNode()
        rclpy.try_shutdown()


def simulator_profile(type_propagation: bool) -> Path:
    """A copy of the simulator's profile (a file of the user's own to tb4, so that the scripts keep it too), with its
    type propagation property removed (Fast DDS's default: on) when `type_propagation`."""
    text = SIMULATOR_LOOPBACK_DDS_PROFILE.read_text()
    if type_propagation:
        text, count = re.subn(r"\s*<propertiesPolicy>.*?</propertiesPolicy>", "", text, flags=re.DOTALL)
        if count != 1:
            raise RuntimeError(f"{SIMULATOR_LOOPBACK_DDS_PROFILE}: expected one propertiesPolicy, found {count}")
    name = "type_propagation_on.xml" if type_propagation else "type_propagation_off.xml"
    path = Path(tempfile.mkdtemp(prefix="bench-discovery-")) / name
    path.write_text(text)
    return path


def _one_script(env: dict[str, str]) -> str:
    """Run one script to its end (bounded) in `env`; its RESULT line's verdict, or why there was none."""
    args = [sys.executable, __file__, "--script", NAMESPACE]
    try:
        done = subprocess.run(args, env=env, capture_output=True, text=True, timeout=SCRIPT_LIMIT)
    except subprocess.TimeoutExpired:  # subprocess.run kills the process it started
        return f"FAIL no end within {SCRIPT_LIMIT:g} s"
    found = re.search(r"^RESULT (.*)$", done.stdout, re.MULTILINE)
    return found.group(1) if found else f"FAIL exit {done.returncode} without a result: {done.stderr[-300:]}"


def measure(profile: Path, scripts: int, parallel: int, busy: int) -> Counter[str]:
    """Start a simulator with `profile`, run `scripts` fresh scripts `parallel` at a time beside `busy` spinning
    processes; returns how many ended each way ("ok", or the failure's text with numbers taken out)."""
    domain = claim_domain_id(150, 230)
    env = ros_environment(domain)
    # the simulator's and every script's
    env["FASTDDS_DEFAULT_PROFILES_FILE"] = str(profile)
    log = Path(tempfile.mkdtemp(prefix="bench-discovery-")) / "sim.log"
    sim = ManagedProcess(
        tb4_command("sim", "--rate", "3", "--world", "warehouse", "--namespace", NAMESPACE), env=env, log_path=log
    )
    spinners = [ManagedProcess([sys.executable, "-c", "while True: pass"]) for _ in range(busy)]
    outcomes: Counter[str] = Counter()
    lock = threading.Lock()
    left = [scripts]

    def worker() -> None:
        while True:
            with lock:
                if left[0] == 0:
                    return
                left[0] -= 1
            verdict = _one_script(env)
            with lock:
                outcomes[re.sub(r"(?<![A-Za-z])\d+(\.\d+)?", "N", verdict)] += 1

    try:
        if not sim.wait_for_output("tb4 sim ready", timeout=60):
            raise RuntimeError(f"the simulator did not start:\n{sim.output()}")
        threads = [threading.Thread(target=worker, daemon=True) for _ in range(parallel)]
        for thread in threads:
            thread.start()
        deadline = time.monotonic() + scripts * SCRIPT_LIMIT
        for thread in threads:
            thread.join(max(0.0, deadline - time.monotonic()))
    finally:
        for spinner in spinners:
            spinner.stop()
        sim.stop()
    return outcomes


def run(quick: bool = False, scripts: int | None = None, parallel: int = 2, busy: int = 2) -> list[dict[str, object]]:
    """Measure both cases; returns rows {name, ours, baseline, baseline_name, unit, ratio, goal}: scripts that
    found the simulator and had their initial pose reported, of those started."""
    if installed_middleware().fast_dds.split(".")[0] in ("1", "2"):
        print("bench_discovery: Fast DDS 2 has no type propagation wait; nothing to measure")
        return []
    scripts = scripts if scripts is not None else (40 if quick else 150)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    cases = {"off": simulator_profile(type_propagation=False), "on": simulator_profile(type_propagation=True)}
    results = {name: measure(profile, scripts, parallel, busy) for name, profile in cases.items()}
    for name, outcomes in results.items():
        print(f"type propagation {name}: {outcomes['ok']}/{scripts} ready")
        for verdict, count in outcomes.most_common():
            if verdict != "ok":
                print(f"  {count} x {verdict[:200]}")
    ours, base = results["off"]["ok"], results["on"]["ok"]
    return [
        {
            "name": f"fresh scripts ready beside {busy} busy cores, {parallel} at a time",
            "ours": ours,
            "baseline": base,
            "baseline_name": "the same profile, type propagation on (Fast DDS's default)",
            "unit": f"of {scripts}",
            "ratio": round(ours / base, 3) if base else None,
            "goal": f"{scripts} of {scripts}",
        }
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="40 scripts per case instead of 150")
    parser.add_argument("--scripts", type=int, help="scripts per case (default 150)")
    parser.add_argument("--parallel", type=int, default=2, help="scripts running at a time")
    parser.add_argument("--busy", type=int, default=2, help="processes spinning a core each")
    parser.add_argument("--script", metavar="NAMESPACE", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.script is not None:
        return script(args.script)
    for r in run(args.quick, args.scripts, args.parallel, args.busy):
        print(f"{r['name']}: {r['ours']} {r['unit']} ({r['baseline_name']}: {r['baseline']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
