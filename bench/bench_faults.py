"""Fault benchmark: the fault cases of issue 40, each measured against its bound in a simulator of its own.

1. The simulator killed (SIGKILL) mid-goal: navigate_to_pose (polled), follow_waypoints, dock. Measured: wall
   seconds from the kill until the navigator's task ends FAILED with an error naming the server.
2. SIGTERM to a navigator script mid-goal (startToPose, and a Simple Commander isTaskComplete loop) and to
   `tb4 run`: wall seconds until it exits (143), and that its goal ended canceled.
3. The battery run empty mid-goal: the goal fails with an error naming the battery, and so does the next one,
   at once.
4. Two navigators preempting each other: the preempted goal ends FAILED, its error saying so.
5. NaN, inf and huge velocity commands, and NaN goals: each refused with a reason, and the robot still navigates.

    python bench/bench_faults.py [--only CASE ...] [--json]

Each case prints its figure beside its bound and whether it passed; the script exits 1 if any bound is missed.
The helpers are the tests' own (tests/ros, tests/e2e): the same checks, timed. Each case claims a ROS domain of
its own and stops every process it started by PID.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))
sys.path.insert(0, str(ROOT))  # the tests' helpers: tests.ros, tests.e2e

from tb4.processes import (  # noqa: E402
    ManagedProcess,
    claim_domain_id,
    release_domain_id,
    remove_stale_shm,
    ros_environment,
    shm_snapshot,
    tb4_command,
)

__all__ = ["CASES", "Outcome", "Case", "run", "run_cases", "main"]

PREEMPTED_WITHIN = 2.0  # wall s from the newer goal's acceptance to the older task's end
AT_ONCE = 5.0  # wall s for a goal refused by a flat battery (the progress checker took 10 s to fail it)
NAVIGATES_WITHIN = 120.0  # wall s for the goal that shows the simulator still navigating after bad input


@dataclass
class Outcome:
    """One case's figure beside its bound; `passed` also covers what the case checks besides the time."""

    name: str
    measured: float
    bound: float
    passed: bool
    detail: str = ""
    unit: str = "s"

    def row(self) -> dict:
        """The bench runner's row: the bound is the baseline."""
        return {
            "name": self.name,
            "ours": self.measured,
            "baseline": self.bound,
            "baseline_name": "bound",
            "unit": self.unit,
            "ratio": self.bound / self.measured if self.measured > 0 else math.inf,
            "goal": f"<= {self.bound:g} {self.unit}" + ("" if self.passed else " MISSED"),
            "passed": self.passed,
            "detail": self.detail,
        }


@dataclass
class Case:
    """One case's world: a claimed ROS domain (this process's nodes join it), its processes, a raw client and
    navigators; all ended when the case ends."""

    name: str
    domain: int = 0
    folder: Path = field(default_factory=lambda: Path(tempfile.mkdtemp(prefix="tb4-bench-faults-")))
    processes: list[ManagedProcess] = field(default_factory=list)
    navigators: list[Any] = field(default_factory=list)
    _ros: Any = None

    @property
    def namespace(self) -> str:
        return f"fault_{self.name}"

    def start_process(self, args: list[str], name: str = "proc", **kwargs: Any) -> ManagedProcess:
        """The tests' start_process: a process of the case's, in its domain, logged, stopped by PID at the end."""
        kwargs.setdefault("env", ros_environment(self.domain))
        proc = ManagedProcess(args, log_path=self.folder / f"{name}-{len(self.processes)}.log", **kwargs)
        self.processes.append(proc)
        return proc

    def start_simulator(self, *options: str) -> ManagedProcess:
        from tb4.ros.simulator import READY_LINE

        proc = self.start_process(tb4_command("sim", *options, "--namespace", self.namespace), name="sim")
        if not proc.wait_for_output(READY_LINE, timeout=90):
            raise RuntimeError(f"the simulator did not start:\n{proc.output()[-3000:]}")
        return proc

    @property
    def ros(self) -> Any:
        """A raw rclpy client (the tests' RosClient), made on first use."""
        if self._ros is None:
            from tests.ros.rosclient import RosClient

            self._ros = RosClient("bench_faults_client")
        return self._ros

    def navigator(self, **kwargs: Any) -> Any:
        from tb4.navigator import TurtleBot4Navigator

        nav = TurtleBot4Navigator(namespace=self.namespace, **kwargs)
        self.navigators.append(nav)
        return nav


@contextlib.contextmanager
def opened(name: str) -> Iterator[Case]:
    """A case in a claimed ROS domain with rclpy initialised; its navigators, client and processes (by PID) ended,
    and the environment put back, however it ends."""
    import rclpy

    case = Case(name, domain=claim_domain_id())
    saved = {key: os.environ.get(key) for key in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")}
    os.environ["ROS_DOMAIN_ID"] = str(case.domain)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    shm_before = shm_snapshot()
    rclpy.init()
    try:
        yield case
    finally:
        for nav in case.navigators:
            nav.destroyNode()
        rclpy.try_shutdown()
        if case._ros is not None:
            case._ros.close()
        for proc in reversed(case.processes):
            proc.stop()
        remove_stale_shm(shm_before)
        release_domain_id(case.domain)
        for key, value in saved.items():  # the bench runner's next module sees the environment it had
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


# --- 1. the simulator killed mid-goal --------------------------------------------------------------------------
def _lost(case: Case, nav: Any, action: str, elapsed: float, what: str) -> Outcome:
    from tests.ros.test_navigator_liveness import FAILED_WITHIN

    from tb4.navigator import TaskResult

    code, message = nav.getTaskError()
    named = message.startswith(f"{action}: the action server") and code != 0
    failed = nav.getResult() is TaskResult.FAILED
    return Outcome(
        f"SIGKILL of the simulator mid {what}: task FAILED naming '{action}' after",
        elapsed,
        FAILED_WITHIN,
        failed and named and elapsed <= FAILED_WITHIN,
        f"{nav.getResult().name}: {message}",
    )


def kill_mid_navigate(case: Case) -> Outcome:
    from tests.ros.test_navigator_liveness import FAR, drive_until_feedback, kill, poll_until_complete
    from tests.ros.test_navigator_tasks import start_localized

    sim = case.start_simulator("--rate", "3", "--world", "warehouse")
    nav = case.navigator()
    start_localized(nav)
    nav.goToPose(nav.getPoseStamped(*FAR))
    drive_until_feedback(nav, "navigate_to_pose")
    return _lost(case, nav, "navigate_to_pose", poll_until_complete(nav, kill(sim)), "goToPose")


def kill_mid_waypoints(case: Case) -> Outcome:
    from tests.ros.test_navigator_liveness import FAR, drive_until_feedback, kill, poll_until_complete
    from tests.ros.test_navigator_tasks import start_localized

    from tb4.navigator import TurtleBot4Directions

    sim = case.start_simulator("--rate", "3", "--world", "warehouse")
    nav = case.navigator()
    start_localized(nav)
    nav.followWaypoints([nav.getPoseStamped([-3.0, 0.0], TurtleBot4Directions.EAST), nav.getPoseStamped(*FAR)])
    drive_until_feedback(nav, "follow_waypoints")
    return _lost(case, nav, "follow_waypoints", poll_until_complete(nav, kill(sim)), "followWaypoints")


def kill_mid_dock(case: Case) -> Outcome:
    from action_msgs.msg import GoalStatus
    from tests.ros.test_navigator_liveness import FAILED_WITHIN, Statuses, kill, run_blocking
    from tests.ros.test_navigator_tasks import run_to_end, start_localized

    from tb4.places import Places

    statuses = Statuses(case.ros, f"/{case.namespace}/dock")
    # real time: docking from the home spot lasts seconds, so the kill comes while it runs
    sim = case.start_simulator("--rate", "1", "--world", "warehouse")
    nav = case.navigator()
    start_localized(nav)
    nav.goToPose(Places.of_world("warehouse").pose("home", nav))
    run_to_end(nav, 120.0)
    thread, box = run_blocking(nav.dock)
    statuses.wait_for(case.ros, GoalStatus.STATUS_EXECUTING, "the dock executing")
    if box:
        return Outcome("SIGKILL of the simulator mid dock", 0.0, FAILED_WITHIN, False, f"docked first: {box}")
    killed = kill(sim)
    thread.join(FAILED_WITHIN + 20)
    elapsed = time.monotonic() - killed
    code, message = nav.getTaskError()
    ok = box == {"value": False} and message.startswith("dock: the action server") and code != 0
    return Outcome(
        "SIGKILL of the simulator mid dock: dock() False naming 'dock' after",
        elapsed,
        FAILED_WITHIN,
        ok and elapsed <= FAILED_WITHIN,
        f"dock() returned {box}: {message}",
    )


# --- 2. SIGTERM mid-goal ---------------------------------------------------------------------------------------
def _sigterm_script(case: Case, kind: str) -> Outcome:
    from action_msgs.msg import GoalStatus
    from tests.ros.test_navigator_liveness import Statuses
    from tests.ros.test_navigator_signals import EXIT_WITHIN, expected_status, signal_and_time_exit, start_script

    statuses = Statuses(case.ros, f"/{case.namespace}/navigate_to_pose")
    case.start_simulator("--rate", "3", "--world", "warehouse")
    script = start_script(case.start_process, case.folder, kind, case.namespace)
    statuses.wait_for(case.ros, GoalStatus.STATUS_EXECUTING, "the script's goal executing", timeout=90)
    code, took = signal_and_time_exit(script, signal.SIGTERM)
    try:
        statuses.wait_for(case.ros, GoalStatus.STATUS_CANCELED, "the goal canceled", timeout=10)
        canceled = True
    except Exception:  # noqa: BLE001 - reported in the outcome
        canceled = False
    ok = code in expected_status(signal.SIGTERM) and canceled and not statuses.seen(GoalStatus.STATUS_SUCCEEDED)
    method = "startToPose" if kind == "turtlebot4" else "an isTaskComplete loop"
    return Outcome(
        f"SIGTERM to a navigator script in {method}: exit, goal canceled, after",
        took,
        EXIT_WITHIN,
        ok and took <= EXIT_WITHIN,
        f"exit status {code}, goal canceled: {canceled}",
    )


def sigterm_start_to_pose(case: Case) -> Outcome:
    return _sigterm_script(case, "turtlebot4")


def sigterm_task_loop(case: Case) -> Outcome:
    return _sigterm_script(case, "simple_commander")


def sigterm_tb4_run(case: Case) -> Outcome:
    from tests.e2e.test_own_missions import LONG_DRIVE
    from tests.ros.test_navigator_liveness import kill
    from tests.ros.test_navigator_signals import EXIT_WITHIN

    (case.folder / "drive.py").write_text(LONG_DRIVE)
    out = case.folder / "runs"
    proc = case.start_process(
        tb4_command("run", str(case.folder / "drive.py"), "--rate", "2", "--output-dir", str(out)), name="tb4_run"
    )
    if not proc.wait_for_output("driving", timeout=120):
        raise RuntimeError(f"the mission never started driving:\n{proc.output()[-3000:]}")
    time.sleep(1.0)  # well into the drive
    sent = kill(proc, signal.SIGTERM)
    code = proc.popen.wait(20)
    took = time.monotonic() - sent
    records = list(out.glob("drive-*/run.json"))
    statuses = []
    if records:
        events = json.loads(records[0].read_text())["events"]
        statuses = [e["status"] for e in events if e.get("action") == "navigate_to_pose" and e["type"] == "result"]
    ok = code == 143 and statuses == ["canceled"] and "arrived" not in proc.output()
    return Outcome(
        "SIGTERM to tb4 run mid-goal: exit, goal canceled, after",
        took,
        EXIT_WITHIN,
        ok and took <= EXIT_WITHIN,
        f"exit status {code}, recorded results {statuses}",
    )


# --- 3. the battery run empty ----------------------------------------------------------------------------------
def battery_empty(case: Case) -> Outcome:
    from tests.ros.test_navigator_tasks import run_to_end, start_localized

    from tb4.navigator import TaskResult
    from tb4.places import Places
    from tb4.sim.create3 import BATTERY_EMPTY

    # 0.2 % of 26 Wh: a few metres of driving, far less than the drive to the loading bay
    sim = case.start_simulator("--rate", "max", "--world", "warehouse", "--battery", "0.002", "--hold")
    nav = case.navigator()
    start_localized(nav)
    places = Places.of_world("warehouse")
    nav.goToPose(places.pose("loading bay", nav))
    run_to_end(nav, 120.0)
    first = (nav.getResult(), nav.getTaskError()[1])
    started = time.monotonic()
    nav.goToPose(places.pose("office", nav))
    run_to_end(nav, 60.0)
    took = time.monotonic() - started
    second = (nav.getResult(), nav.getTaskError()[1])
    logged = sim.wait_for_output("The battery is empty (0 %)", timeout=10)
    named = all(result is TaskResult.FAILED and message == BATTERY_EMPTY for result, message in (first, second))
    return Outcome(
        "battery run empty: goals FAILED naming the battery; the next one after",
        took,
        AT_ONCE,
        named and logged and took <= AT_ONCE,
        f"first goal {first[0].name}: {first[1]!r}; next goal {second[0].name}: {second[1]!r}; "
        f"simulator log says so: {logged}",
    )


# --- 4. two navigators preempting each other ------------------------------------------------------------------
def preemption(case: Case) -> Outcome:
    from tests.ros.test_navigator_liveness import drive_until_feedback
    from tests.ros.test_navigator_tasks import run_to_end, start_localized

    from tb4.navigator import TaskResult
    from tb4.places import Places

    # 5x real time: each goal is a minute of driving, still running when the other navigator's goal comes
    sim = case.start_simulator("--rate", "5", "--world", "warehouse")
    first = case.navigator(node_name="first_navigator")
    second = case.navigator(node_name="second_navigator")
    start_localized(first)
    second.waitUntilNav2Active()
    places = Places.of_world("warehouse")
    first.goToPose(places.pose("loading bay", first))
    drive_until_feedback(first, "the first navigator's goal")
    sent = time.monotonic()
    second.goToPose(places.pose("office", second))
    run_to_end(first, 30.0)
    took = time.monotonic() - sent
    second.cancelTask()
    result, (code, message) = first.getResult(), first.getTaskError()
    logged = sim.wait_for_output("preempted by the newer navigate_to_pose goal", timeout=10)
    ok = result is TaskResult.FAILED and "preempted" in message and logged
    return Outcome(
        "two navigators: the preempted task FAILED saying 'preempted' after",
        took,
        PREEMPTED_WITHIN,
        ok and took <= PREEMPTED_WITHIN,
        f"{result.name} ({code}): {message!r}; simulator logs the preemption: {logged}",
    )


# --- 5. NaN / inf / huge velocity commands and NaN goals -----------------------------------------------------
def bad_input(case: Case) -> Outcome:
    from geometry_msgs.msg import Twist
    from nav2_msgs.action import NavigateToPose
    from tests.ros.test_navigator_tasks import run_to_end, start_localized

    from tb4.core.waits import wait_until
    from tb4.navigator import TaskResult
    from tb4.places import Places

    sim = case.start_simulator("--rate", "5", "--world", "warehouse")
    nav = case.navigator()
    start_localized(nav)
    ros = case.ros
    cmd = ros.node.create_publisher(Twist, f"/{case.namespace}/cmd_vel", 10)
    ros.wait_for(cmd.get_subscription_count, lambda n: n > 0, what="the simulator's cmd_vel reader")
    time.sleep(0.5)  # the reader matches this writer too (reliable: then nothing is dropped)
    refused = []
    for linear, angular in ((math.nan, 0.0), (0.0, math.inf), (1e9, 0.0), (-math.inf, math.nan)):
        bad = Twist()
        bad.linear.x, bad.angular.z = linear, angular
        before = sim.output().count("cmd_vel ignored")
        cmd.publish(bad)
        refused.append(wait_until(lambda n=before: sim.output().count("cmd_vel ignored") > n, 5.0))
        time.sleep(1.1)  # the simulator says so at most once a second
    # a NaN goal: the navigator refuses it before sending; sent raw, the simulator refuses it with a reason
    nan_goal = nav.getPoseStamped([0.0, 0.0], 0)
    nan_goal.pose.position.x = math.nan
    try:
        nav.goToPose(nan_goal)
        navigator_error = "accepted"
    except ValueError as exc:
        navigator_error = str(exc)
    action = f"/{case.namespace}/navigate_to_pose"
    status, result = ros.action(NavigateToPose, action, NavigateToPose.Goal(pose=nan_goal))
    raw = "rejected" if status == -1 else f"status {status}: {getattr(result, 'error_msg', '')!r}"
    # and the robot still navigates
    started = time.monotonic()
    nav.goToPose(Places.of_world("warehouse").pose("packing station", nav))
    run_to_end(nav, NAVIGATES_WITHIN)
    took = time.monotonic() - started
    navigated = nav.getResult() is TaskResult.SUCCEEDED and sim.alive()
    ok = all(refused) and navigator_error != "accepted" and status != 4 and navigated
    return Outcome(
        "NaN/inf/huge cmd_vel and NaN goals refused; then a goal across the warehouse SUCCEEDED in",
        took,
        NAVIGATES_WITHIN,
        ok and took <= NAVIGATES_WITHIN,
        f"cmd_vel refused with a reason: {refused}; navigator: {navigator_error!r}; raw NaN goal: {raw}; "
        f"next goal {nav.getResult().name}",
    )


CASES: dict[str, Callable[[Case], Outcome]] = {
    "kill_navigate": kill_mid_navigate,
    "kill_waypoints": kill_mid_waypoints,
    "kill_dock": kill_mid_dock,
    "sigterm_start_to_pose": sigterm_start_to_pose,
    "sigterm_task_loop": sigterm_task_loop,
    "sigterm_tb4_run": sigterm_tb4_run,
    "battery_empty": battery_empty,
    "preemption": preemption,
    "bad_input": bad_input,
}


def run_cases(names: list[str]) -> list[Outcome]:
    """Run the named cases one after another; a case that raises is a failed outcome with its error."""
    outcomes = []
    for name in names:
        started = time.monotonic()
        print(f"[faults] {name} ...", file=sys.stderr, flush=True)
        try:
            with opened(name) as case:
                outcome = CASES[name](case)
        except Exception as exc:  # noqa: BLE001 - the case failed: say how, go on with the next
            outcome = Outcome(name, math.nan, math.nan, False, f"{type(exc).__name__}: {exc}"[:2000])
        print(
            f"[faults] {name}: {outcome.measured:.2f} {outcome.unit} (bound {outcome.bound:g}) "
            f"{'pass' if outcome.passed else 'FAIL'} in {time.monotonic() - started:.0f} s; {outcome.detail}",
            file=sys.stderr,
            flush=True,
        )
        outcomes.append(outcome)
    return outcomes


def run(quick: bool = False) -> list[dict]:
    """Rows for the bench runner: every case (the same with --quick: each is one measurement)."""
    return [outcome.row() for outcome in run_cases(list(CASES))]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", nargs="+", choices=list(CASES), help="run only these cases")
    parser.add_argument("--json", action="store_true", help="print the outcomes as JSON")
    args = parser.parse_args(argv)
    # with --json, stdout holds the JSON alone: what the tests' helpers print goes to stderr
    with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
        outcomes = run_cases(args.only or list(CASES))
    if args.json:
        # JSON holds no nan or inf (a case that raised has no figure): those as strings
        safe = [
            {k: v if not isinstance(v, float) or math.isfinite(v) else str(v) for k, v in o.row().items()}
            for o in outcomes
        ]
        json.dump(safe, sys.stdout, indent=1)
        print()
    else:
        for o in outcomes:
            verdict = "pass" if o.passed else "FAIL"
            print(f"{verdict}  {o.name} {o.measured:.2f} {o.unit} (bound {o.bound:g} {o.unit})\n      {o.detail}")
    return 0 if all(o.passed for o in outcomes) else 1


if __name__ == "__main__":
    raise SystemExit(main())
