"""Soak benchmark: navigation goals in a row with charging, as a battery-aware patrol drives them, against one
`tb4 sim --rate max` for the whole run. A TurtleBot4Navigator, in a process of its own as a user's script is,
sends goals between the world's named places in turn; when the battery is below the patrol tutorial's low mark it
goes home, docks, charges to its high mark and undocks, as `tb4 run patrol_loop` does.

Measured, the last hundred goals beside the first hundred of the same run (the baseline): goals succeeded and
failed (with the reasons), the simulator's and the navigator's resident memory (VmRSS of /proc/PID/status, read
by the navigator's process after every goal), and the time per goal, wall and sim.

    python bench/bench_soak.py [--goals N] [--wall-limit SECONDS] [--world NAME] [--json]

Bounded: each goal gets at most GOAL_LIMIT wall seconds (then it is canceled and counted failed), the whole run
--wall-limit (the navigator's process is stopped a minute past it); the simulator and the navigator run in a ROS
domain claimed for them and are stopped by their PIDs.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.processes import (  # noqa: E402
    ManagedProcess,
    claim_domain_id,
    release_domain_id,
    ros_environment,
    tb4_command,
)

__all__ = ["GoalSample", "Charge", "Driver", "Soak", "rss_kb", "rows", "summary", "soak", "run", "main"]

ROUTE = ("office", "loading bay", "packing station", "home")  # the warehouse's places, visited in turn
WINDOW = 100  # goals compared at each end of the run
GOAL_LIMIT = 300.0  # wall s for one goal (the longest leg is about 40 m)
WALL_LIMIT = 3 * 3600.0
CHARGE_STEP = 15.0  # sim s between battery checks on the dock, as the patrol tutorial


def rss_kb(pid: int | str = "self") -> int | None:
    """The resident memory (VmRSS, kB) of a process, or None when it is gone."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        return None
    return None


@dataclass
class GoalSample:
    """One navigation goal of the soak, and the memory of both processes right after it ended."""

    index: int
    place: str
    purpose: str  # "patrol", or "charge" for the drive home before docking
    succeeded: bool
    reason: str  # the result and the task error when it did not succeed
    wall: float
    sim: float
    battery: float  # fraction, before the goal
    sim_rss_kb: int | None
    nav_rss_kb: int | None


@dataclass
class Charge:
    """One stop on the dock: the battery before and after, what it cost, and what went wrong if anything."""

    before_goal: int
    battery_before: float
    battery_after: float
    wall: float
    sim: float
    problem: str = ""


class Driver:
    """The navigator's side, in a process of its own as a user's patrol script is (its memory is the navigator's,
    not the bench's bookkeeping): goals in turn, charging when low, each goal's sample appended to a file."""

    def __init__(self, world: str, sim_pid: int, out: Path, goal_limit: float = GOAL_LIMIT) -> None:
        from tb4.places import Places
        from tb4.tutorials.common import open_navigator
        from tb4.tutorials.patrol_loop import BatteryMonitor

        self.sim_pid = sim_pid
        self.goal_limit = goal_limit
        self.out = out
        self.goals = 0
        self.places = Places.of_world(world)
        self.places.require(ROUTE)
        self.nav = open_navigator()
        self.battery = BatteryMonitor()

    def close(self) -> None:
        from tb4.tutorials.common import close_navigator

        self.battery.close()
        close_navigator(self.nav)

    def _write(self, kind: str, record: Any) -> None:
        with self.out.open("a", encoding="utf-8") as handle:
            handle.write(json.dumps({kind: asdict(record) if not isinstance(record, str) else record}) + "\n")

    def _sim_seconds(self) -> float:
        return self.nav.get_clock().now().nanoseconds / 1e9

    def _drive(self, place: str, purpose: str) -> GoalSample:
        """One goal to a named place, polled as a user's script polls; canceled at the goal limit."""
        from tb4.navigator import TaskResult

        battery = self.battery.percent()
        wall0, sim0 = time.perf_counter(), self._sim_seconds()
        reason = ""
        if not self.nav.goToPose(self.places.pose(place, self.nav)):
            reason = f"rejected: {self.nav.getTaskError()[1]}"
        else:
            deadline = time.monotonic() + self.goal_limit
            while not self.nav.isTaskComplete():
                if time.monotonic() > deadline:
                    self.nav.cancelTask()
                    reason = f"no result within {self.goal_limit:g} wall s (canceled)"
                    break
            if not reason and self.nav.getResult() is not TaskResult.SUCCEEDED:
                code, message = self.nav.getTaskError()
                reason = f"{self.nav.getResult().name} ({code}): {message}"
        sample = GoalSample(
            index=self.goals,
            place=place,
            purpose=purpose,
            succeeded=not reason,
            reason=reason,
            wall=time.perf_counter() - wall0,
            sim=self._sim_seconds() - sim0,
            battery=battery,
            sim_rss_kb=rss_kb(self.sim_pid),
            nav_rss_kb=rss_kb(),
        )
        self.goals += 1
        self._write("goal", sample)
        return sample

    def _charge(self, deadline: float) -> None:
        """Home, dock, charge to the patrol's high mark, undock (the home drive is one of the goals)."""
        from tb4.tutorials.common import sim_sleep
        from tb4.tutorials.patrol_loop import BATTERY_HIGH

        before = self.battery.percent()
        wall0, sim0 = time.perf_counter(), self._sim_seconds()
        charge = Charge(self.goals, before, before, 0.0, 0.0)
        self._drive("home", "charge")
        if not self.nav.dock() or not self.nav.getDockedStatus():
            charge.problem = f"dock failed: {self.nav.getTaskError()[1]}"
        else:
            while self.battery.percent() < BATTERY_HIGH and time.monotonic() < deadline:
                sim_sleep(self.nav, CHARGE_STEP)
            if not self.nav.undock():
                charge.problem = f"undock failed: {self.nav.getTaskError()[1]}"
        charge.battery_after = self.battery.percent()
        charge.wall, charge.sim = time.perf_counter() - wall0, self._sim_seconds() - sim0
        self._write("charge", charge)

    def run(self, goals: int, wall_limit: float) -> None:
        """Send `goals` goals (the drives home to charge count among them), within `wall_limit` wall seconds."""
        from tb4.tutorials.common import start_on_dock
        from tb4.tutorials.patrol_loop import BATTERY_LOW

        deadline = time.monotonic() + wall_limit
        start_on_dock(self.nav)
        turn = 0
        while self.goals < goals:
            if time.monotonic() > deadline:
                self._write("stopped", f"wall limit ({wall_limit:g} s) reached after {self.goals} goals")
                return
            if self.battery.percent() < BATTERY_LOW:
                self._charge(deadline)
                continue
            self._drive(ROUTE[turn % len(ROUTE)], "patrol")
            turn += 1


class Soak:
    """The run: the simulator and the navigator's process, both stopped by PID, and what the navigator recorded."""

    def __init__(self, world: str) -> None:
        """Start the simulator in a domain of its own (waits, bounded, until it serves)."""
        self.world = world
        self.domain = claim_domain_id()
        self.folder = Path(tempfile.mkdtemp(prefix="tb4-bench-soak-"))
        self.record = self.folder / "goals.jsonl"
        self.sim = ManagedProcess(
            tb4_command("sim", "--rate", "max", "--world", world),
            env=ros_environment(self.domain),
            log_path=self.folder / "sim.log",
        )
        self.driver: ManagedProcess | None = None
        self.samples: list[GoalSample] = []
        self.charges: list[Charge] = []
        self.stopped = ""  # why the run ended early, if it did
        from tb4.ros.simulator import READY_LINE

        if not self.sim.wait_for_output(READY_LINE, timeout=90):
            self.close()
            raise RuntimeError(f"the simulator did not start:\n{self.sim.output()[-3000:]}")

    def close(self) -> None:
        """Stop the navigator's process and the simulator by their PIDs, give the domain back."""
        if self.driver is not None:
            self.driver.stop()
        self.sim.stop()
        release_domain_id(self.domain)

    def _read(self) -> None:
        self.samples, self.charges = [], []
        if not self.record.exists():
            return
        for line in self.record.read_text(encoding="utf-8").splitlines():
            entry = json.loads(line)
            if "goal" in entry:
                self.samples.append(GoalSample(**entry["goal"]))
            elif "charge" in entry:
                self.charges.append(Charge(**entry["charge"]))
            elif "stopped" in entry:
                self.stopped = entry["stopped"]

    def run(self, goals: int, wall_limit: float, progress: bool = True) -> None:
        """The navigator's process sends `goals` goals; it is stopped (by PID) a minute past `wall_limit`."""
        args = [sys.executable, __file__, "--drive", "--sim-pid", str(self.sim.pid), "--goals", str(goals)]
        args += ["--wall-limit", str(wall_limit), "--world", self.world, "--record", str(self.record)]
        self.driver = ManagedProcess(args, env=ros_environment(self.domain), log_path=self.folder / "navigator.log")
        deadline = time.monotonic() + wall_limit + 60.0
        reported = 0
        while self.driver.alive() and self.sim.alive() and time.monotonic() < deadline:
            time.sleep(2.0)
            self._read()
            if progress and len(self.samples) >= reported + 50:
                reported = len(self.samples) // 50 * 50
                last = self.samples[-1]
                print(
                    f"[soak] {len(self.samples)}/{goals} goals, {sum(s.succeeded for s in self.samples)} succeeded, "
                    f"{len(self.charges)} charges, battery {100 * last.battery:.0f} %, sim RSS {last.sim_rss_kb} kB, "
                    f"navigator RSS {last.nav_rss_kb} kB",
                    file=sys.stderr,
                    flush=True,
                )
        self._read()
        if not self.sim.alive():
            self.stopped = self.stopped or f"the simulator exited ({self.sim.popen.returncode})"
        elif self.driver.alive():
            self.stopped = self.stopped or f"the navigator's process still ran {wall_limit + 60:g} s in: stopped"
        elif self.driver.popen.returncode != 0:
            tail = self.driver.output()[-2000:]
            self.stopped = self.stopped or f"the navigator's process failed ({self.driver.popen.returncode}): {tail}"


def _mean(values: list[Any]) -> float:
    known = [v for v in values if v is not None]
    return statistics.fmean(known) if known else float("nan")


def rows(samples: list[GoalSample], charges: list[Charge], window: int = WINDOW) -> list[dict]:
    """The figures for the bench runner: the last `window` goals beside the first `window` (at most half the run
    each), and the goals that succeeded beside those sent."""
    if not samples:
        return []
    n = min(window, max(1, len(samples) // 2))
    first, last = samples[:n], samples[-n:]
    ok = sum(s.succeeded for s in samples)
    out: list[dict] = [
        {
            "name": f"soak: goals succeeded of {len(samples)} sent ({len(charges)} charges on the dock)",
            "ours": ok,
            "baseline": len(samples),
            "baseline_name": "goals sent",
            "unit": "goals",
            "ratio": ok / len(samples),
            "goal": "all (ratio 1.0)",
        }
    ]
    for what, key in (("simulator", "sim_rss_kb"), ("navigator", "nav_rss_kb")):
        early = _mean([getattr(s, key) for s in first]) / 1024
        late = _mean([getattr(s, key) for s in last]) / 1024
        out.append(
            {
                "name": f"soak: {what} RSS, mean of the last {n} goals (growth {1024 * (late - early):+.0f} kB)",
                "ours": late,
                "baseline": early,
                "baseline_name": f"first {n} goals",
                "unit": "MB",
                "ratio": early / late,
                "goal": "no growth (ratio >= 0.99)",
            }
        )
    # means: each window holds the same cycle of legs (a median would jump between the legs' lengths)
    for what, key in (("wall", "wall"), ("sim", "sim")):
        early = statistics.fmean(getattr(s, key) for s in first)
        late = statistics.fmean(getattr(s, key) for s in last)
        out.append(
            {
                "name": f"soak: {what} time per goal, mean of the last {n} goals",
                "ours": late,
                "baseline": early,
                "baseline_name": f"first {n} goals",
                "unit": "s",
                "ratio": early / late,
                "goal": "no slowdown (ratio >= 0.9)",
            }
        )
    return out


def summary(soak: Soak) -> dict[str, Any]:
    """What the run saw besides the figures: failures by reason, the charges, why it stopped early."""
    failures = Counter(s.reason for s in soak.samples if not s.succeeded)
    return {
        "world": soak.world,
        "goals": len(soak.samples),
        "succeeded": sum(s.succeeded for s in soak.samples),
        "failures": dict(failures),
        "charges": [asdict(c) for c in soak.charges],
        "stopped_early": soak.stopped,
        "logs": str(soak.folder),
    }


def soak(goals: int, wall_limit: float = WALL_LIMIT, world: str = "warehouse") -> tuple[list[dict], dict, list]:
    """Run the soak; returns its rows, its summary and every goal's sample."""
    run_ = Soak(world)
    try:
        run_.run(goals, wall_limit)
    finally:
        run_.close()
    return rows(run_.samples, run_.charges), summary(run_), [asdict(s) for s in run_.samples]


def run(quick: bool = False) -> list[dict]:
    """Rows {name, ours, baseline, unit, ratio, goal} for the bench runner (--quick: 40 goals, else 1,000)."""
    figures, info, _ = soak(40 if quick else 1000)
    for reason, count in info["failures"].items():
        print(f"[soak] failed {count}x: {reason}", file=sys.stderr)
    if info["stopped_early"]:
        print(f"[soak] stopped early: {info['stopped_early']}", file=sys.stderr)
    return figures


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--goals", type=int, default=1000, help="goals to send (default 1000)")
    parser.add_argument("--wall-limit", type=float, default=WALL_LIMIT, help="wall seconds for the whole run")
    parser.add_argument("--world", default="warehouse", help="a world with the places home, office, loading bay ...")
    parser.add_argument("--json", action="store_true", help="print the figures, summary and samples as JSON")
    # the navigator's process (started by the bench itself)
    parser.add_argument("--drive", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--sim-pid", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--record", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.goals < 2:
        parser.error("--goals must be at least 2")
    if args.drive:
        driver = Driver(args.world, args.sim_pid, args.record)
        try:
            driver.run(args.goals, args.wall_limit)
        finally:
            driver.close()
        return 0
    figures, info, samples = soak(args.goals, args.wall_limit, args.world)
    if args.json:
        json.dump({"rows": figures, "summary": info, "samples": samples}, sys.stdout, indent=1)
        print()
    else:
        for row in figures:
            print(
                f"{row['name']}: {row['ours']:.4g} {row['unit']} vs {row['baseline']:.4g} ({row['baseline_name']}), "
                f"ratio {row['ratio']:.3f}, goal {row['goal']}"
            )
        print(json.dumps({k: v for k, v in info.items() if k != "charges"}, indent=1))
        print(f"charges: {len(info['charges'])}, problems: {[c['problem'] for c in info['charges'] if c['problem']]}")
    complete = info["goals"] == args.goals and not info["stopped_early"]
    return 0 if complete and info["succeeded"] == info["goals"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
