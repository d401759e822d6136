"""Whole-system figures: the simulator process over DDS, full navigation, and `tb4 run` wall times.

Each is printed beside a baseline from the same run: the same work in-process without DDS, or the mission's own
duration in sim time (what the same mission takes on a real robot).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402

__all__ = ["run"]

WAIT_SECONDS = 10**6  # sim s: Nav2's Wait longer than any measurement, canceled after it

GOAL = (-13.0, 9.0, -math.pi / 2)


def _in_process_navigation() -> tuple[float, float]:
    """(sim seconds, wall seconds) of the same navigation with Simulation + NavigationCore stepped directly."""
    from tb4.nav.server import NavigationCore
    from tb4.sim.simulation import Simulation
    from tb4.sim.world import load_world

    world = load_world("warehouse")
    sim = Simulation.from_world(world)
    nav = NavigationCore(world.map, robot=sim)
    nav.set_initial_pose(0.0, 0.0, 0.0)
    undock = sim.start_undock()
    while not undock.done:
        sim.step(5)
        nav.step(sim.time)
    t0, w0 = sim.time, time.monotonic()
    task = nav.start_navigate_to_pose(GOAL)
    while not task.done and sim.time - t0 < 600:
        sim.step(5)
        nav.step(sim.time)
    assert task.status == "succeeded", task.result()
    return sim.time - t0, time.monotonic() - w0


def _still_core_rtf(seconds: float) -> float:
    """The simulator process's loop without DDS while its robot stands still on the dock running Nav2's Wait: SimLoop
    itself (physics, the navigation core; a running task keeps --rate max unpaced and every tick one control period)
    and a scan at the rate the simulator publishes `scan` (tb4.ros.robot.common.RATES), so both sides of the
    comparison ray-cast and tick alike. (With nothing to do, the simulator now runs at WAITING_RATE by design.)"""
    from tb4.nav.server import NavigationCore
    from tb4.ros.loop import SimLoop
    from tb4.ros.robot.common import RATES
    from tb4.sim.simulation import Simulation
    from tb4.sim.world import load_world

    world = load_world("warehouse")
    sim = Simulation.from_world(world)
    loop = SimLoop(sim, NavigationCore(world.map, robot=sim), rate=float("inf"))
    loop.every(RATES["scan"], lambda _now: sim.scan())
    loop.nav.start_wait(WAIT_SECONDS)
    w0 = time.monotonic()
    while time.monotonic() - w0 < seconds:
        loop.tick(fast_forward=True)
    return sim.time / (time.monotonic() - w0)


class _Client:
    """Raw rclpy client in its own context (the bench measures the simulator, not our navigator)."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rosgraph_msgs.msg import Clock

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("bench_client", context=self.context)
        self.clock = 0.0
        self.node.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _on_clock(self, msg) -> None:
        self.clock = msg.clock.sec + msg.clock.nanosec * 1e-9

    def _spin(self) -> None:
        while self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:
                return

    def action(self, action_type, name: str, goal, timeout: float = 120.0):
        from tb4.core.waits import wait_for_future
        from tb4.ros.action_client import ActionClient

        client = ActionClient(self.node, action_type, name)
        if not client.wait_for_server(timeout_sec=20):
            raise RuntimeError(f"no action server {name}")
        handle = wait_for_future(client.send_goal_async(goal), 10, f"{name} acceptance")
        return wait_for_future(handle.get_result_async(), timeout, f"{name} result")

    def still_rtf(self, seconds: float) -> float:
        """Sim s per wall s while Nav2's Wait runs (the robot still, the loop unpaced), over `seconds`; then cancel."""
        from nav2_msgs.action import Wait

        from tb4.core.waits import wait_for_future
        from tb4.ros.action_client import ActionClient

        client = ActionClient(self.node, Wait, "wait")
        if not client.wait_for_server(timeout_sec=20):
            raise RuntimeError("no action server wait")
        goal = Wait.Goal()
        goal.time.sec = int(WAIT_SECONDS)
        handle = wait_for_future(client.send_goal_async(goal), 10, "wait acceptance")
        if not handle.accepted:
            raise RuntimeError("wait goal rejected")
        time.sleep(0.5)  # the goal running
        s0, w0 = self.clock, time.monotonic()
        time.sleep(seconds)
        rtf = (self.clock - s0) / (time.monotonic() - w0)
        wait_for_future(handle.cancel_goal_async(), 10, "wait cancel")
        return rtf

    def close(self) -> None:
        import rclpy

        rclpy.try_shutdown(context=self.context)
        self.thread.join(2)
        self.node.destroy_node()


def _dds_figures(env: dict[str, str]) -> tuple[float, float, float]:
    """(RTF of a still robot running Nav2's Wait, publishing over DDS; navigation sim s, navigation wall s) from a
    real simulator process."""
    import os

    from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
    from irobot_create_msgs.action import Undock
    from nav2_msgs.action import NavigateToPose

    from tb4.ros.convert import yaw_to_quaternion

    os.environ["ROS_DOMAIN_ID"] = env["ROS_DOMAIN_ID"]
    sim = ManagedProcess(
        tb4_command("sim", "--rate", "max"),
        env=env,
        log_path=Path(tempfile.mkstemp(suffix=".log")[1]),
    )
    client = None
    try:
        if not sim.wait_for_output("tb4 sim ready", 60):
            raise RuntimeError(sim.output())
        client = _Client()
        deadline = time.monotonic() + 20
        while client.clock == 0.0 and time.monotonic() < deadline:
            time.sleep(0.05)
        still_rtf = client.still_rtf(5.0)
        initial = client.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.pose.pose.orientation.w = 1.0
        time.sleep(0.5)
        initial.publish(msg)
        time.sleep(0.5)
        client.action(Undock, "undock", Undock.Goal())
        goal = NavigateToPose.Goal()
        goal.pose = PoseStamped()
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x, goal.pose.pose.position.y = GOAL[0], GOAL[1]
        goal.pose.pose.orientation = yaw_to_quaternion(GOAL[2])
        s0, w0 = client.clock, time.monotonic()
        result = client.action(NavigateToPose, "navigate_to_pose", goal)
        if result.status != 4:
            raise RuntimeError(f"navigation failed: {result.result.error_msg}")
        return still_rtf, client.clock - s0, time.monotonic() - w0
    finally:
        if client is not None:
            client.close()
        sim.stop()


def _tb4_run(env: dict[str, str], *args: str) -> tuple[float, float]:
    """(wall s from process start to exit, sim s the mission took) of `tb4 run ...`."""
    out = Path(tempfile.mkdtemp())
    start = time.monotonic()
    proc = subprocess.run(
        tb4_command("run", *args, "--json", "--output-dir", str(out)),
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    wall = time.monotonic() - start
    if proc.returncode != 0:
        raise RuntimeError(f"tb4 run {' '.join(args)} failed: {proc.stdout[-800:]} {proc.stderr[-800:]}")
    end = json.loads(proc.stdout.strip().splitlines()[-1])
    record = json.loads(Path(end["record"]).read_text())
    times = [e["t"] for e in record["events"]]
    return wall, max(times) - min(times)  # from the first command to the last result, in sim time


def run(quick: bool = False) -> list[dict]:
    env = ros_environment(claim_domain_id())
    rows = []
    core_still = _still_core_rtf(3.0 if quick else 6.0)
    still_rtf, nav_sim, nav_wall = _dds_figures(env)
    rows.append(
        {
            "name": "simulator process real-time factor, robot still running Nav2's Wait, publishing over DDS",
            "ours": still_rtf,
            "baseline": core_still,
            "baseline_name": "same loop in-process, no DDS",
            "unit": "x",
            "ratio": still_rtf / core_still,
            "goal": ">= 50x",
        }
    )
    base_sim, base_wall = _in_process_navigation()
    rows.append(
        {
            "name": "navigation across the warehouse, whole stack + DDS (RTF)",
            "ours": nav_sim / nav_wall,
            "baseline": base_sim / base_wall,
            "baseline_name": "same navigation in-process, no DDS",
            "unit": "x",
            "ratio": (nav_sim / nav_wall) / (base_sim / base_wall),
            "goal": ">= 100x over DDS, >= 150x in-process (issue 15)",
        }
    )
    wall, sim_time = _tb4_run(env, "nav_to_pose")
    rows.append(
        {
            "name": "tb4 run nav_to_pose: cold process start to exit",
            "ours": wall,
            "baseline": sim_time,
            "baseline_name": "the mission in real time (sim s)",
            "unit": "s",
            "ratio": sim_time / wall,
            "goal": "<= 6 s wall (issue 15)",
        }
    )
    if not quick:
        wall, sim_time = _tb4_run(env, "patrol_loop", "--battery", "0.21", "--laps", "1")
        rows.append(
            {
                "name": "tb4 run patrol_loop: lap with a full charge cycle",
                "ours": wall,
                "baseline": sim_time,
                "baseline_name": "the mission in real time (sim s)",
                "unit": "s",
                "ratio": sim_time / wall,
                "goal": "<= 30 s wall (issue 15)",
            }
        )
    return rows


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)
