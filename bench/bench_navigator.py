"""Benchmark of the navigator against raw rclpy action calls, measured side by side against one simulator.

1. Per-goal overhead: a goal the server ends at once (dock_robot with an unknown dock id: accepted, then
   aborted), from the call to the result, through BasicNavigator (goal + isTaskComplete loop + getResult) and
   through a raw rclpy ActionClient (send_goal_async / get_result_async, spin_until_future_complete).
2. Result-to-next-goal gap in a waypoint mission (short goToPose legs): from the moment a goal's result reaches
   the client to the moment the next goal is accepted. Ours, raw rclpy, and a loop that polls every 100 ms
   (the pattern of upstream's dock()/undock() and many user scripts) for reference.

    python bench/bench_navigator.py [--quick]

Starts `tb4 sim --rate max` itself on ROS_DOMAIN_ID (default: one derived from the PID) and stops it by PID.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "src"))

from tb4.processes import ManagedProcess, ros_environment, tb4_command  # noqa: E402

__all__ = ["run"]

GOAL_OVERHEAD_RATIO = 0.5  # ours may cost at most 2x the raw round trip
GOAL_GAP_MS = 20.0
LEGS = [(-1.0, 0.0, 0.0), (-1.6, 0.0, math.pi), (-1.0, 0.0, 0.0)]


def _start_simulator(domain: int) -> ManagedProcess:
    log = Path(tempfile.mkdtemp(prefix="bench-nav-")) / "sim.log"
    proc = ManagedProcess(
        tb4_command("sim", "--rate", "max", "--world", "warehouse"),
        env=ros_environment(domain),
        log_path=log,
    )
    if not proc.wait_for_output("tb4 sim ready", timeout=60):
        proc.stop()
        raise RuntimeError(f"simulator did not start:\n{proc.output()}")
    return proc


class RawClient:
    """What a script written against rclpy alone does: its own node, spin_until_future_complete per step."""

    def __init__(self, poll: float | None = None) -> None:
        """poll=None: spin_until_future_complete in the caller; poll=P: an executor thread completes futures and
        the caller checks future.done() every P seconds (a sleep-poll loop)."""
        import rclpy
        from nav2_msgs.action import DockRobot, NavigateToPose
        from rclpy.executors import SingleThreadedExecutor

        from tb4.ros.action_client import ActionClient

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("raw_bench_client", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.dock: Any = ActionClient(self.node, DockRobot, "dock_robot")
        self.nav: Any = ActionClient(self.node, NavigateToPose, "navigate_to_pose")
        for client in (self.dock, self.nav):
            if not client.wait_for_server(timeout_sec=20.0):
                raise RuntimeError("raw client: action server not found")
        self.poll = poll
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        if poll is not None:
            self._thread = threading.Thread(target=self._background, daemon=True)
            self._thread.start()

    def _background(self) -> None:
        while not self._stop.is_set() and self.context.ok():
            self.executor.spin_once(timeout_sec=0.05)

    def _spin(self, future: Any, timeout: float = 60.0) -> Any:
        if self.poll is None:
            self.executor.spin_until_future_complete(future, timeout_sec=timeout)
        else:
            deadline = time.monotonic() + timeout
            while not future.done() and time.monotonic() < deadline:
                time.sleep(self.poll)
        if not future.done():
            raise RuntimeError("raw client: timed out")
        return future.result()

    def trivial_goal(self) -> int:
        from nav2_msgs.action import DockRobot

        handle = self._spin(self.dock.send_goal_async(DockRobot.Goal(use_dock_id=True, dock_id="nope")))
        return int(self._spin(handle.get_result_async()).status)

    def mission(self, poses: list[Any]) -> list[float]:
        """Gaps (s) between a result's arrival (stamped by its done-callback) and the next goal's acceptance."""
        from nav2_msgs.action import NavigateToPose

        gaps: list[float] = []
        arrived = 0.0
        for i, pose in enumerate(poses):
            handle = self._spin(self.nav.send_goal_async(NavigateToPose.Goal(pose=pose)))
            if i > 0:
                gaps.append(time.perf_counter() - arrived)
            future = handle.get_result_async()
            stamp: dict[str, float] = {}
            future.add_done_callback(lambda _f, s=stamp: s.setdefault("t", time.perf_counter()))
            self._spin(future, timeout=120.0)
            arrived = stamp.get("t", time.perf_counter())
            if future.result().status != 4:
                raise RuntimeError(f"raw mission leg {i} ended with status {future.result().status}")
        return gaps

    def close(self) -> None:
        import rclpy

        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _ours_trivial_goal(nav: Any) -> Any:
    nav.dockRobotByID("nope")
    while not nav.isTaskComplete():
        pass
    return nav.getResult()


def _ours_mission(nav: Any, poses: list[Any]) -> list[float]:
    gaps: list[float] = []
    arrived = 0.0
    for i, pose in enumerate(poses):
        if not nav.goToPose(pose):
            raise RuntimeError("navigator: goal rejected")
        if i > 0:
            gaps.append(time.perf_counter() - arrived)
        stamp: dict[str, float] = {}
        nav.result_future.add_done_callback(lambda _f, s=stamp: s.setdefault("t", time.perf_counter()))
        while not nav.isTaskComplete():
            nav.getFeedback()
        arrived = stamp.get("t", time.perf_counter())
        if nav.getResult().name != "SUCCEEDED":
            raise RuntimeError(f"navigator mission leg {i}: {nav.getResult()} {nav.getTaskError()}")
    return gaps


def _median_ms(samples: list[float]) -> float:
    return statistics.median(samples) * 1e3


def _timed(fn: Callable[[], Any]) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def run(quick: bool = False) -> list[dict]:
    """Measure; returns rows {name, ours, baseline, unit, ratio, goal}."""
    os.environ.setdefault("ROS_DOMAIN_ID", str(10 + os.getpid() % 90))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    domain = int(os.environ["ROS_DOMAIN_ID"])
    sim = _start_simulator(domain)
    import rclpy

    from tb4.navigator import BasicNavigator
    from tb4.ros.convert import pose_stamped

    rclpy.init()
    nav = BasicNavigator(node_name="bench_navigator")
    raw = RawClient()
    poller = RawClient(poll=0.1)
    rows: list[dict] = []
    try:
        nav.setInitialPose(pose_stamped((0.0, 0.0, 0.0)))
        nav.waitUntilNav2Active()
        nav.undockRobot()
        while not nav.isTaskComplete():
            pass
        if nav.getResult().name != "SUCCEEDED":
            raise RuntimeError(f"undock failed: {nav.getTaskError()}")

        # 1. per-goal overhead, interleaved so machine load hits both alike
        repeats = 15 if quick else 60
        for _ in range(3):  # warm-up (discovery, first allocations)
            _ours_trivial_goal(nav)
            raw.trivial_goal()
        ours_t: list[float] = []
        raw_t: list[float] = []
        for _ in range(repeats):
            ours_t.append(_timed(lambda: _ours_trivial_goal(nav)))
            raw_t.append(_timed(raw.trivial_goal))
        ours, base = _median_ms(ours_t), _median_ms(raw_t)
        print(f"trivial goal round trip: navigator {ours:.2f} ms, raw rclpy {base:.2f} ms (median of {repeats})")
        rows.append(
            {
                "name": "per-goal overhead (send→accept→result)",
                "ours": round(ours, 2),
                "baseline": round(base, 2),
                "unit": "ms",
                "ratio": round(base / ours, 2),
                "goal": f"ratio >= {GOAL_OVERHEAD_RATIO:g} (at most 2x raw rclpy)",
            }
        )

        # 2. result -> next goal in a waypoint mission
        laps = 1 if quick else 3
        poses = [pose_stamped(p) for p in LEGS * laps]
        ours_gaps = _ours_mission(nav, poses)
        raw_gaps = raw.mission(poses)
        poll_gaps = poller.mission(poses)
        ours, base, poll = _median_ms(ours_gaps), _median_ms(raw_gaps), _median_ms(poll_gaps)
        print(
            f"result -> next goal accepted ({len(ours_gaps)} gaps each): navigator {ours:.2f} ms, raw rclpy "
            f"{base:.2f} ms, 100 ms poll loop {poll:.2f} ms"
        )
        for name, baseline in (
            ("mission gap: result→next goal accepted", base),
            ("mission gap vs 100 ms poll loop", poll),
        ):
            rows.append(
                {
                    "name": name,
                    "ours": round(ours, 2),
                    "baseline": round(baseline, 2),
                    "unit": "ms",
                    "ratio": round(baseline / ours, 2),
                    "goal": f"<= {GOAL_GAP_MS:g} ms",
                }
            )
    finally:
        raw.close()
        poller.close()
        nav.destroyNode()
        rclpy.try_shutdown()
        sim.stop()
    return rows


def _met(row: dict) -> bool:
    if row["name"].startswith("per-goal"):
        return row["ratio"] >= GOAL_OVERHEAD_RATIO
    return row["ours"] <= GOAL_GAP_MS


def _print_table(rows: list[dict]) -> None:
    print(f"{'benchmark':44} {'ours':>10} {'baseline':>10} {'ratio':>7}  goal")
    for r in rows:
        print(
            f"{r['name']:44} {r['ours']:>8.2f}{r['unit']} {r['baseline']:>8.2f}{r['unit']} {r['ratio']:>6.2f}x  "
            f"{r['goal']} [{'met' if _met(r) else 'MISSED'}]"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    args = parser.parse_args(argv)
    _print_table(run(quick=args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
