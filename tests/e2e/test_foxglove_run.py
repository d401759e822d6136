"""`tb4 run ... --foxglove`: the run's robot seen through a real Foxglove WebSocket client
(tests/e2e/foxglove_client.py), and a port in use stopping the run before its simulator starts. Apart from
test_foxglove_live.py, whose module-wide simulator would share this worker's DDS domain with the run's."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
pytest.importorskip("foxglove", reason="the [foxglove] extra is not installed")
pytest.importorskip("websockets", reason="the test client needs websockets (the [viewer] extra)")

from tb4.processes import ManagedProcess, remove_stale_shm, shm_snapshot  # noqa: E402

from .foxglove_client import FoxgloveClient  # noqa: E402
from .tutorial_runs import TB4, environment, run_json  # noqa: E402


def test_tb4_run_serves_the_run_to_foxglove(tmp_path: Path) -> None:
    """A run's robot as the app sees it: the goal, the plan to it, and odometry moving."""
    before = shm_snapshot()
    run = ManagedProcess(
        [
            *TB4,
            "run",
            "nav_to_pose",
            "--rate",
            "3",
            "--foxglove",
            "0",
            "--json",
            "--no-picture",
            "--time-limit",
            "150",
            "--output-dir",
            str(tmp_path),
        ],
        env=environment(),
        log_path=tmp_path / "run.log",
    )
    try:
        assert run.wait_for_output("foxglove: ws://", 120), run.output()
        url = re.search(r"foxglove: (ws://127\.0\.0\.1:\d+)", run.output())
        assert url, run.output()
        with FoxgloveClient(url.group(1)) as client:
            client.wait_for_channels(["/odom", "/plan", "/goals/poses"])
            client.subscribe(["/odom", "/plan", "/goals/poses"])
            _, _, goals = client.next_message(["/goals/poses"], timeout=60)
            assert goals.header.frame_id == "map" and len(goals.poses) == 1
            goal = goals.poses[0].position
            assert (goal.x, goal.y) == pytest.approx((-13.0, 9.0), abs=1e-6)  # nav_to_pose's goal
            _, _, plan = client.next_message(["/plan"], timeout=60, predicate=lambda p: len(p.poses) > 1)
            end = plan.poses[-1].pose.position
            assert math.hypot(end.x - goal.x, end.y - goal.y) < 0.5
            _, _, start = client.next_message(["/odom"], timeout=30)
            client.next_message(
                ["/odom"],
                timeout=60,
                predicate=lambda o: (
                    math.hypot(
                        o.pose.pose.position.x - start.pose.pose.position.x,
                        o.pose.pose.position.y - start.pose.pose.position.y,
                    )
                    > 0.3
                ),
            )
    finally:
        run.stop(timeout=30)
        remove_stale_shm(before)


def test_a_port_in_use_stops_tb4_run_before_the_simulator_starts(busy_port: int, tmp_path: Path) -> None:
    code, events, stderr = run_json(["nav_to_pose", "--foxglove", str(busy_port)], tmp_path, timeout=120)
    assert code == 2, (events, stderr)
    end = events[-1]
    assert end["event"] == "end" and "is in use" in end["reason"], end
    assert not (Path(end["run_dir"]) / "sim.log").exists()  # no simulator was started
