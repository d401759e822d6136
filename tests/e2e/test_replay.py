"""`tb4 replay` on runs of a user-style script over DDS: the replay (no DDS) is the recording bit for bit.

The mission exercises what a user's script sends a robot: an initial pose, undock, a goal canceled halfway, raw
velocity commands on cmd_vel, a spin, waypoints, a costmap clear, poses through, and a dock. Live, each input lands
on whatever tick DDS delivers it; the replay must land it on the same one.
"""

from __future__ import annotations

import json
import subprocess
import textwrap
from pathlib import Path

import pytest
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message

from .tutorial_runs import TB4, environment, record_of, run_json

MISSION = textwrap.dedent(
    """\
    #!/usr/bin/env python3
    # A user's mission: the same file runs on the robot (no import of tb4).
    import time

    import rclpy
    from geometry_msgs.msg import Twist
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator


    def main():
        rclpy.init()
        navigator = TurtleBot4Navigator()
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.goToPose(navigator.getPoseStamped([-3.0, 2.0], TurtleBot4Directions.WEST))
        deadline = time.monotonic() + 20.0
        while navigator.getFeedback() is None and time.monotonic() < deadline:
            navigator.isTaskComplete()
            time.sleep(0.01)
        navigator.cancelTask()  # on its way
        cmd = navigator.create_publisher(Twist, "cmd_vel", 10)
        twist = Twist()
        twist.angular.z = 0.8
        for _ in range(15):
            cmd.publish(twist)
            time.sleep(0.02)
        navigator.spin(spin_dist=1.0)
        navigator.clearAllCostmaps()
        navigator.startFollowWaypoints(
            [
                navigator.getPoseStamped([-1.0, 1.0], TurtleBot4Directions.EAST),
                navigator.getPoseStamped([-0.5, -1.0], TurtleBot4Directions.SOUTH),
            ]
        )
        navigator.startThroughPoses([navigator.getPoseStamped([-1.0, 0.0], TurtleBot4Directions.NORTH)])
        navigator.dock()
        for start in (lambda: navigator.undockRobot("create3_dock"), lambda: navigator.dockRobotByID("home")):
            start()  # Nav2's docking_server this time
            while not navigator.isTaskComplete():
                time.sleep(0.02)
        rclpy.shutdown()
        return 0


    if __name__ == "__main__":
        raise SystemExit(main())
    """
)


def _replay(run_dir: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*TB4, "replay", str(run_dir), *extra],
        env=environment(),
        capture_output=True,
        text=True,
        timeout=180,
        stdin=subprocess.DEVNULL,
    )


def test_a_users_script_run_over_dds_replays_bit_for_bit(tmp_path: Path) -> None:
    (tmp_path / "busy_mission.py").write_text(MISSION)
    # at 20x, not max: the goal the mission cancels on its way takes a second of wall time, where at --rate max a
    # quiet machine can finish it before the cancel arrives (the goal then succeeds, and no cancel is journaled)
    args = [str(tmp_path / "busy_mission.py"), "--seed", "11", "--rate", "20"]
    code, events, _ = run_json(args, tmp_path / "runs")
    assert code == 0, events[-1]
    record = record_of(events)
    run_dir = Path(events[-1]["run_dir"])
    journal = record["replay"]
    assert journal["untracked"] == [], journal  # every input of this mission is one replay can redo
    assert journal["inputs"] >= 10 and (run_dir / journal["journal"]).is_file()
    calls = [json.loads(line).get("call") for line in (run_dir / journal["journal"]).read_text().splitlines()]
    for call in (
        "nav.set_initial_pose",
        "sim.start_undock",
        "nav.start_navigate_to_pose",
        "task.cancel",
        "sim.set_velocity_command",
        "nav.start_spin",
        "nav.clear_global",
        "nav.start_follow_waypoints",
        "nav.start_navigate_through_poses",
        "sim.start_dock",
        "docking.start_undock_robot",
        "docking.start_dock_robot",
    ):
        assert call in calls, (call, sorted({c for c in calls if c}))

    done = _replay(run_dir, "--json", "--picture", str(tmp_path / "replay.png"))
    assert done.returncode == 0, done.stdout + done.stderr
    report = json.loads(done.stdout.splitlines()[0])
    assert report["identical"] and report["replayed_digest"] == journal["digest"], report
    assert report["ticks"] == journal["ticks"] and report["input_errors"] == []
    final = record["trajectory"][-1]  # the record's last sample (rounded) against the replay's exact end
    assert abs(report["final_poses"][0][0] - final[1]) < 0.05 and abs(report["final_poses"][0][1] - final[2]) < 0.05
    assert (tmp_path / "replay.png").stat().st_size > 0

    # the same replay served by a simulator for a recording: it stops after the run's last tick, where the robot
    # stood at the end of the live run
    mcap = tmp_path / "replay.mcap"
    served = _replay(run_dir, "--record", str(mcap), "--rate", "max")
    assert served.returncode == 0, served.stdout + served.stderr
    assert f"sim time {record['summary']['sim_time']:.1f} s" in served.stdout, served.stdout
    truths = []
    with mcap.open("rb") as stream:
        for _, _channel, message in make_reader(stream).iter_messages(topics=["/ground_truth"]):
            truths.append(deserialize_message(message.data, Odometry))
    assert truths, "the replay's recording holds no /ground_truth"
    first, last = truths[0].header.stamp, truths[-1]
    # the recording holds the replay from its start: the loop waits for the recorder (it missed 12 s once before)
    assert first.sec + first.nanosec * 1e-9 < 1.0, first
    end_x, end_y, _ = report["final_poses"][0]
    assert (last.pose.pose.position.x, last.pose.pose.position.y) == pytest.approx((end_x, end_y), abs=1e-6)


def test_a_tampered_journal_replays_differently_and_says_where(tmp_path: Path) -> None:
    (tmp_path / "busy_mission.py").write_text(MISSION)
    code, events, _ = run_json([str(tmp_path / "busy_mission.py"), "--seed", "4", "--exact"], tmp_path / "runs")
    assert code == 0, events[-1]
    run_dir = Path(events[-1]["run_dir"])
    path = run_dir / record_of(events)["replay"]["journal"]
    lines = path.read_text().splitlines()
    for k, line in enumerate(lines):  # the first waypoint half a metre off where it was
        data = json.loads(line)
        if data.get("call") == "nav.start_follow_waypoints":
            data["args"][0][0]["__tuple__"][0] += 0.5
            lines[k] = json.dumps(data)
            break
    path.write_text("\n".join(lines) + "\n")
    done = _replay(run_dir)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "DIFFERS" in done.stdout and "first differs at tick" in done.stdout, done.stdout
