"""Benchmark: does every request of a burst get its answer? Goals and service calls, against `tb4 sim`.

A client (one node, one thread that sends and spins, as a plain script does) sends GOALS navigate_to_pose goals
evenly over SECONDS (500 in 5 s by default), then waits a bounded time for every goal response (accepted or
rejected); then CALLS lifecycle get_state calls (bt_navigator/get_state) the same way. A goal or call without an
answer by then is lost. Two clients: tb4's (tb4.ros.action_client.ActionClient and tb4.ros.qos.REQUESTS, as the
navigator uses) and rclpy's own with rclpy's default QoS (what a plain script uses).

The baseline, measured in the same run: rclpy's client against a raw rclpy server (default QoS, single-threaded
rclpy.spin, goals accepted and succeeded at once, get_state answered at once) in a process of its own: what rclpy
and Fast DDS alone deliver on this machine, so a loss on our side is told from one underneath.

    python bench/bench_burst.py [--quick] [--goals N] [--calls N] [--seconds S]

Loopback only, in a ROS_DOMAIN_ID of its own (150-230); every process it starts is stopped by PID.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402

__all__ = ["run", "Burst", "send_burst"]

ANSWER_WAIT = 20.0  # s after the burst's last request that its answers may still come
SERVER_WAIT = 30.0  # s for a server to be discovered
RAW_NAMESPACE = "raw_baseline"  # the raw rclpy server's namespace (the simulator's robot has none)


@dataclass
class Burst:
    """How one burst went: requests sent, answered (and of the goals, accepted), the seconds it took to send them
    and until the last answer came."""

    sent: int = 0
    answered: int = 0
    accepted: int = 0
    send_seconds: float = 0.0
    last_answer_seconds: float = 0.0

    @property
    def lost(self) -> int:
        return self.sent - self.answered


def send_burst(executor: Any, send: Any, count: int, seconds: float, answer_wait: float = ANSWER_WAIT) -> Burst:
    """Call `send()` `count` times evenly over `seconds`, spinning `executor` in between (this thread only, so no
    future can be completed behind our back), then spin until every future is done or `answer_wait` s passed.

    Args:
        executor: the client node's executor.
        send: sends one request and returns the future its answer completes.
        count: requests to send.
        seconds: the burst's length.
        answer_wait: how long after the last request the answers may take.

    Returns:
        The burst's figures; a goal counts as accepted when its answer is a goal handle that says so.
    """
    futures: list[Any] = []
    start = time.monotonic()
    period = seconds / max(count, 1)
    last_answer = [start]

    def answered(_future: Any) -> None:
        last_answer[0] = time.monotonic()

    for i in range(count):
        due = start + i * period
        while (wait := due - time.monotonic()) > 0:
            executor.spin_once(timeout_sec=wait)
        future = send()
        future.add_done_callback(answered)
        futures.append(future)
    sent_at = time.monotonic()
    deadline = sent_at + answer_wait
    while not all(f.done() for f in futures) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    done = [f for f in futures if f.done() and f.exception() is None]
    accepted = sum(1 for f in done if bool(getattr(f.result(), "accepted", False)))
    return Burst(count, len(done), accepted, sent_at - start, last_answer[0] - start)


class BurstClient:
    """The client: a node in a context of its own with one action client and one service client, either rclpy's
    own with rclpy's default QoS (`tb4_client` False: what a plain script uses) or tb4's (the navigator's: tb4's
    ActionClient and tb4.ros.qos.REQUESTS)."""

    def __init__(self, namespace: str, tb4_client: bool) -> None:
        import rclpy
        from action_msgs.srv import CancelGoal
        from lifecycle_msgs.srv import GetState
        from nav2_msgs.action import NavigateToPose
        from rclpy.action import ActionClient as RclpyActionClient
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import qos_profile_services_default

        from tb4.ros.action_client import ActionClient
        from tb4.ros.qos import REQUESTS

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("burst_client", namespace=namespace, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        qos = REQUESTS if tb4_client else qos_profile_services_default
        self.actions = (ActionClient if tb4_client else RclpyActionClient)(
            self.node, NavigateToPose, "navigate_to_pose"
        )
        self.service = self.node.create_client(GetState, "bt_navigator/get_state", qos_profile=qos)
        self._cancel = self.node.create_client(CancelGoal, "navigate_to_pose/_action/cancel_goal", qos_profile=qos)
        deadline = time.monotonic() + SERVER_WAIT
        while not (self.actions.server_is_ready() and self.service.service_is_ready()):
            if time.monotonic() > deadline:
                raise RuntimeError(f"burst client: no navigate_to_pose or get_state server in /{namespace}")
            self.executor.spin_once(timeout_sec=0.1)
        self._goal = NavigateToPose.Goal()
        self._goal.pose.header.frame_id = "map"
        self._goal.pose.pose.position.x = -1.0
        self._goal.pose.pose.orientation.w = 1.0
        self._request = GetState.Request()

    def goals(self, count: int, seconds: float) -> Burst:
        burst = send_burst(self.executor, lambda: self.actions.send_goal_async(self._goal), count, seconds)
        self._cancel_all()
        return burst

    def calls(self, count: int, seconds: float) -> Burst:
        return send_burst(self.executor, lambda: self.service.call_async(self._request), count, seconds)

    def _cancel_all(self) -> None:
        """Cancel every goal of the server (a zero id and stamp name them all), waiting a bounded time."""
        from action_msgs.srv import CancelGoal

        future = self._cancel.call_async(CancelGoal.Request())
        deadline = time.monotonic() + ANSWER_WAIT
        while not future.done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        import rclpy

        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def serve_raw() -> None:
    """The baseline server (run as `bench_burst.py --serve-raw`): raw rclpy, default QoS, rclpy.spin."""
    import rclpy
    from lifecycle_msgs.msg import State
    from lifecycle_msgs.srv import GetState
    from nav2_msgs.action import NavigateToPose
    from rclpy.action import ActionServer

    rclpy.init()
    node = rclpy.create_node("bt_navigator", namespace=RAW_NAMESPACE)

    def execute(goal_handle: Any) -> Any:
        goal_handle.succeed()
        return NavigateToPose.Result()

    def get_state(_request: Any, response: Any) -> Any:
        response.current_state.id = State.PRIMARY_STATE_ACTIVE
        response.current_state.label = "active"
        return response

    ActionServer(node, NavigateToPose, "/" + RAW_NAMESPACE + "/navigate_to_pose", execute)
    node.create_service(GetState, "~/get_state", get_state)
    print("raw server ready", flush=True)
    with contextlib.suppress(KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        rclpy.spin(node)


def _start(args: list[str], ready: str, domain: int, name: str) -> ManagedProcess:
    log = Path(tempfile.mkdtemp(prefix="bench-burst-")) / f"{name}.log"
    proc = ManagedProcess(args, env=ros_environment(domain), log_path=log)
    if not proc.wait_for_output(ready, timeout=60):
        proc.stop()
        raise RuntimeError(f"{name} did not start:\n{proc.output()}")
    return proc


def measure(namespace: str, tb4_client: bool, goals: int, calls: int, seconds: float) -> tuple[Burst, Burst]:
    client = BurstClient(namespace, tb4_client)
    try:
        client.calls(5, 0.1)  # warm-up: the first request of a fresh client also waits for discovery
        return client.goals(goals, seconds), client.calls(calls, seconds)
    finally:
        client.close()


def _row(name: str, ours: Burst, base: Burst) -> dict:
    return {
        "name": name,
        "ours": ours.answered,
        "baseline": base.answered,
        "unit": f"of {ours.sent}",
        "ratio": round(ours.answered / base.answered, 3) if base.answered else None,
        "goal": f"{ours.sent} of {ours.sent} answered",
    }


def run(quick: bool = False, goals: int | None = None, calls: int | None = None, seconds: float = 5.0) -> list[dict]:
    """Measure; returns rows {name, ours, baseline, unit, ratio, goal} (answers received of requests sent)."""
    goals = goals if goals is not None else (100 if quick else 500)
    calls = calls if calls is not None else goals
    domain = claim_domain_id(150, 230)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    sim = _start(tb4_command("sim", "--world", "warehouse"), "tb4 sim ready", domain, "sim")
    raw = _start([sys.executable, __file__, "--serve-raw"], "raw server ready", domain, "raw-server")
    # rclpy's client first on both servers: a server lists every goal of the last 15 minutes in each status message
    # (rclpy's and Nav2's result_timeout), and the client reads the whole list at each wake-up; each server then
    # starts from none. tb4's client comes last, on a simulator already holding the first burst's goals.
    cases = (
        ("rclpy client -> tb4 sim", "", False),
        ("rclpy client -> rclpy server", RAW_NAMESPACE, False),
        ("tb4 client -> tb4 sim", "", True),
    )
    results: dict[str, tuple[Burst, Burst]] = {}
    try:
        for name, namespace, tb4_client in cases:
            results[name] = measure(namespace, tb4_client, goals, calls, seconds)
    finally:
        raw.stop()
        sim.stop()
    for name, (goal_burst, call_burst) in results.items():
        for what, burst in (("goals", goal_burst), ("get_state calls", call_burst)):
            print(
                f"{name:29} {what:16} answered {burst.answered}/{burst.sent} (lost {burst.lost}); sent in "
                f"{burst.send_seconds:.2f} s, last answer at {burst.last_answer_seconds:.2f} s"
                + (f"; accepted {burst.accepted}" if what == "goals" else "")
            )
    base_goals, base_calls = results["rclpy client -> rclpy server"]
    rows = []
    for name in ("tb4 client -> tb4 sim", "rclpy client -> tb4 sim"):
        ours_goals, ours_calls = results[name]
        rows.append(_row(f"burst goal responses, {name}", ours_goals, base_goals))
        rows.append(_row(f"burst get_state replies, {name}", ours_calls, base_calls))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 requests of each kind instead of 500")
    parser.add_argument("--goals", type=int, help="goals in the burst (default 500)")
    parser.add_argument("--calls", type=int, help="service calls in the burst (default: as many as goals)")
    parser.add_argument("--seconds", type=float, default=5.0, help="the burst's length")
    parser.add_argument("--serve-raw", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve_raw:
        serve_raw()
        return 0
    rows = run(args.quick, args.goals, args.calls, args.seconds)
    for r in rows:
        print(f"{r['name']:48} {r['ours']:>5} {r['unit']} (rclpy client -> rclpy server: {r['baseline']})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
