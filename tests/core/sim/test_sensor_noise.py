"""The seeded sensor faults of tb4 sim (on by default, --exact turns them off) and the ground truth kept beside
the estimate in the run record."""

from __future__ import annotations

import json
import math
import threading

import numpy as np
import pytest

from tb4.core.maps import OccupancyMap
from tb4.core.robot_params import load_robot_params
from tb4.ros.run_record import RunRecord
from tb4.sim.simulation import Simulation

pytestmark = pytest.mark.core

RES = 0.05


def room() -> OccupancyMap:
    data = np.zeros((80, 80), dtype=np.int8)
    data[:2, :] = data[-2:, :] = data[:, :2] = data[:, -2:] = 100
    return OccupancyMap(data, RES)


def drive(sim: Simulation, seconds: float, v: float = 0.3, w: float = 0.0) -> None:
    for _ in range(round(seconds / sim.physics_dt)):
        sim.set_velocity_command(v, w)
        sim.step(1)


def test_lidar_dropouts_are_seeded_and_at_the_configured_rate() -> None:
    params = load_robot_params(overrides={"lidar": {"dropout_probability": 0.2, "noise_stddev": 0.0}})
    scans = []
    for _ in range(2):
        sim = Simulation(room(), (2.0, 2.0, 0.0), (2.0, 2.0, 0.0), params=params, seed=5, lidar_noise=True)
        scans.append(np.asarray(sim.scan().ranges))
    np.testing.assert_array_equal(scans[0], scans[1])
    lost = np.mean(~np.isfinite(scans[0]))  # every beam hits a wall in this room
    assert 0.12 < lost < 0.28
    exact = Simulation(room(), (2.0, 2.0, 0.0), (2.0, 2.0, 0.0), params=params, seed=5)
    assert np.all(np.isfinite(exact.scan().ranges))


def test_odometry_drift_is_seeded_and_absent_when_exact() -> None:
    ends = []
    for seed in (1, 1, 2):
        sim = Simulation(room(), (1.0, 2.0, 0.0), (1.0, 2.0, 0.0), seed=seed, odom_noise=True, physics_dt=0.01)
        drive(sim, 6.0, 0.3, 0.2)
        o = sim.odometry()
        ends.append((o.x, o.y, o.yaw))
    assert ends[0] == ends[1] and ends[0] != ends[2]
    sim = Simulation(room(), (1.0, 2.0, 0.0), (1.0, 2.0, 0.0), seed=1, physics_dt=0.01)
    drive(sim, 6.0, 0.3, 0.2)
    t, o = sim.pose(), sim.odometry()
    # exact: odometry is the true motion from the start pose
    assert math.hypot(o.x, o.y) == pytest.approx(math.hypot(t.x - 1.0, t.y - 2.0), abs=1e-6)


def test_bump_makes_odometry_slip_forward() -> None:
    params = load_robot_params(overrides={"odometry": {"bump_slip_fraction": 1.0}})
    sim = Simulation(room(), (3.4, 2.0, 0.0), (3.4, 2.0, 0.0), params=params, seed=0, odom_noise=True)
    drive(sim, 4.0, 0.3)  # into the east wall, and keep pushing
    assert sim.in_contact
    travelled = sim.pose().x - 3.4
    assert sim.odometry().x > travelled + 0.005  # the wheels reported motion the robot did not make


def test_run_record_keeps_truth_and_estimate_and_writes_without_deadlock(tmp_path) -> None:
    record = RunRecord("room", tmp_path / "run.json")
    for i in range(5):
        record.sample(0.2 * i, float(i), 0.0, 0.0)
        record.estimate(0.2 * i, float(i) + 0.1, 0.0, math.radians(2.0))
    done = threading.Event()
    threading.Thread(target=lambda: (record.write({"sim_time": 1.0}), done.set()), daemon=True).start()
    assert done.wait(10.0), "writing the record hung"
    data = json.loads((tmp_path / "run.json").read_text())
    assert len(data["trajectory"]) == len(data["estimates"]) == 5
    err = data["localization_error"]
    assert err["mean_position_error"] == pytest.approx(0.1) and err["mean_heading_error_deg"] == pytest.approx(2.0)
    assert RunRecord("room", tmp_path / "x.json").localization_error() is None


def test_run_picture_draws_the_estimate_beside_the_truth(tmp_path) -> None:
    from PIL import Image

    from tb4.runner.picture import render_run
    from tb4.sim.world import load_world

    world = load_world("depot")
    record = RunRecord("depot", tmp_path / "run.json")
    for i in range(30):
        record.sample(0.2 * i, 0.1 * i, 0.0, 0.0)
        record.estimate(0.2 * i, 0.1 * i, 0.3, 0.0)  # 0.3 m off, so the dashed line is visible apart
    data = record.to_dict({"sim_time": 6.0, "localization": "amcl"})
    with_estimate = render_run(world, data, tmp_path / "amcl.png", title="amcl")
    data["summary"]["localization"] = "truth"
    truth_only = render_run(world, data, tmp_path / "truth.png", title="truth")
    with Image.open(with_estimate) as a, Image.open(truth_only) as b:
        pa, pb = np.asarray(a.convert("RGB")), np.asarray(b.convert("RGB"))
    red = np.array([0xE5, 0x39, 0x35])
    assert np.sum(np.all(np.abs(pa.astype(int) - red) < 20, axis=-1)) > np.sum(
        np.all(np.abs(pb.astype(int) - red) < 20, axis=-1)
    )


def test_run_panel_pairs_each_estimate_with_the_truth_of_its_time() -> None:
    from tb4.runner.display import format_status_line
    from tb4.runner.localization_error import LocalizationErrorTracker

    tracker = LocalizationErrorTracker()
    assert tracker.add_estimate(0.0, 0.0, 0.0, 0.0) is None  # no truth yet
    for i in range(100):
        tracker.add_truth(0.05 * i, 0.26 * 0.05 * i, 0.0, 0.0)  # driving along x
    assert tracker.add_estimate(2.0, 0.52 + 0.03, 0.04, math.radians(2.0)) == pytest.approx(0.05, abs=1e-6)
    assert tracker.heading_error_deg == pytest.approx(2.0)
    assert tracker.add_estimate(60.0, 0.0, 0.0, 0.0) is None  # no truth of that time: not paired
    assert tracker.add_estimate(math.nan, 0.0, 0.0, 0.0) is None
    tracker.add_truth(0.0, 5.0, 5.0, 0.0)  # sim clock restarted: history dropped
    assert tracker.add_estimate(0.0, 5.0, 5.1, 0.0) == pytest.approx(0.1)
    line = format_status_line({"task": "navigate_to_pose", "localization_error": 0.05, "sim_time": 3.0})
    assert "localization 5 cm off" in line


def test_an_estimate_ahead_of_its_truth_pairs_when_the_truth_comes() -> None:
    """amcl_pose and ground_truth come from two writers: the estimate can be in first (stress run s33: the one of
    71.6 s came while the truths had reached 71.45 s). It waits for the truth instead of going unpaired."""
    from tb4.runner.localization_error import LocalizationErrorTracker

    tracker = LocalizationErrorTracker()
    for i in range(10):
        assert tracker.add_truth(0.05 * i, 0.01 * i, 0.0, 0.0) is None  # no estimate waits
    assert tracker.add_estimate(0.6, 0.06 + 0.2, 0.0, 0.0) is None  # ahead of the truth (0.45 s so far): it waits
    assert tracker.add_truth(0.5, 0.05, 0.0, 0.0) is None  # still before it
    assert tracker.add_truth(0.55, 0.055, 0.0, 0.0) is None
    assert tracker.add_truth(0.6, 0.06, 0.0, 0.0) == pytest.approx(0.2)  # its truth: paired
    assert tracker.position_error == pytest.approx(0.2)
    assert tracker.add_truth(0.65, 0.065, 0.0, 0.0) is None  # paired once
    assert tracker.add_estimate(0.7, 0.07, 0.0, 0.0) is None
    assert tracker.add_truth(0.7, 0.07, 0.0, 0.0) == 0.0  # exactly on the truth: an error of 0, not "unpaired"
    # one whose truth never comes (a gap in the truth stream) ends unpaired once a later truth is in
    assert tracker.add_estimate(0.8, 9.0, 9.0, 0.0) is None
    assert tracker.add_truth(1.0, 0.1, 0.0, 0.0) is None and tracker.position_error == 0.0  # the last paired
    # a hostile far-future estimate waiting first does not hold back one whose truth comes
    assert tracker.add_estimate(1e9, 0.0, 0.0, 0.0) is None
    assert tracker.add_estimate(1.1, 0.11 + 0.3, 0.0, 0.0) is None
    assert tracker.add_truth(1.1, 0.11, 0.0, 0.0) == pytest.approx(0.3)
    # waiting is bounded: a clock far ahead (a hostile stamp) keeps at most a few, and a new run drops them
    for k in range(100):
        tracker.add_estimate(1e9 + k, 0.0, 0.0, 0.0)
    assert len(tracker._waiting) == 8
    tracker.add_truth(0.0, 0.0, 0.0, 0.0)
    assert not tracker._waiting


def test_run_panel_decodes_only_the_truth_it_pairs() -> None:
    """The monitor hands over ground_truth undecoded: the pairing is the same, and only paired samples are read."""
    from tb4.runner.localization_error import LocalizationErrorTracker

    eager, lazy = LocalizationErrorTracker(), LocalizationErrorTracker()
    decoded: list[int] = []

    def later(i: int):
        def pose() -> tuple[float, float, float]:
            decoded.append(i)
            return (0.26 * 0.05 * i, 0.0, 0.0)

        return pose

    for i in range(100):
        eager.add_truth(0.05 * i, 0.26 * 0.05 * i, 0.0, 0.0)
        lazy.add_truth_later(0.05 * i, later(i))
    for t in (2.0, 2.02, 3.5, 60.0):
        assert lazy.add_estimate(t, 0.55, 0.04, math.radians(2.0)) == eager.add_estimate(
            t, 0.55, 0.04, math.radians(2.0)
        )
        assert lazy.heading_error_deg == eager.heading_error_deg
    assert lazy.add_estimate(2.0, 0.55, 0.04, 0.0) == eager.add_estimate(2.0, 0.55, 0.04, 0.0)  # decoded once
    assert decoded == [40, 70]
    lazy.add_truth_later(5.0, lambda: (math.nan, 0.0, 0.0))  # a pose add_truth would drop: never paired
    assert lazy.add_estimate(5.0, 0.0, 0.0, 0.0) is None
