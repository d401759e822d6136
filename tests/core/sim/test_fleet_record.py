"""A fleet's run record holds every robot's part (trajectory, goals, results, plans), and its picture draws each
robot in its own colour; a one-robot record keeps the layout it always had."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tb4.ros.run_record import RECORD_VERSION, RunRecord

pytestmark = pytest.mark.core

FLEET = ("/robot1", "/robot2", "/robot3")


def _fleet_record(tmp_path) -> RunRecord:
    record = RunRecord("depot", tmp_path / "run.json", FLEET)
    for k, namespace in enumerate(FLEET):
        part = record.robot(namespace)
        for i in range(20):
            part.sample(0.2 * i, 0.1 * i, float(k), 0.0)
        part.goal("navigate_to_pose", 1.0, [(2.0, float(k), 0.0)], goal_id=k)
        part.plan(1.0, np.array([[0.0, float(k)], [2.0, float(k)]]))
        part.result("navigate_to_pose", 3.0, "succeeded" if k != 2 else "aborted", k, 0, "")
    return record


def test_a_fleet_record_holds_every_robots_goals_results_and_trajectory(tmp_path) -> None:
    record = _fleet_record(tmp_path)
    data = json.loads(record.write({"sim_time": 4.0}).read_text())
    assert data["version"] == RECORD_VERSION and sorted(data["robots"]) == list(FLEET)
    for k, namespace in enumerate(FLEET):
        part = data["robots"][namespace]
        assert len(part["trajectory"]) == 20 and part["trajectory"][0][2] == float(k)
        assert [e["poses"] for e in part["events"] if e["type"] == "goal"] == [[[2.0, float(k), 0.0]]]
        statuses = [e["status"] for e in part["events"] if e["type"] == "result"]
        assert statuses == ["succeeded" if k != 2 else "aborted"]
        assert len(part["plans"]) == 1
    # the top level is the first robot's part, as in a one-robot record
    assert data["trajectory"] == data["robots"]["/robot1"]["trajectory"]
    assert data["events"] == data["robots"]["/robot1"]["events"]


def test_a_one_robot_record_keeps_its_layout(tmp_path) -> None:
    record = RunRecord("depot", tmp_path / "run.json")
    assert record.robot("") is record
    record.sample(0.0, 1.0, 2.0, 0.0)
    data = json.loads(record.write({"sim_time": 1.0}).read_text())
    assert "robots" not in data and data["trajectory"] == [[0.0, 1.0, 2.0, 0.0]]
    assert {"world", "summary", "trajectory", "estimates", "events", "plans", "recoveries"} <= set(data)


def test_the_fleet_picture_draws_each_robot_in_its_colour(tmp_path) -> None:
    from PIL import Image

    from tb4.runner.picture import render_run, robot_parts
    from tb4.sim.render import FLEET_COLORS
    from tb4.sim.world import load_world

    data = _fleet_record(tmp_path).to_dict({"sim_time": 4.0})
    assert list(robot_parts(data)) == list(FLEET)
    out = render_run(load_world("depot"), data, tmp_path / "fleet.png", title="fleet")
    with Image.open(out) as image:
        pixels = np.asarray(image.convert("RGB")).astype(int)
    for color in FLEET_COLORS[:3]:
        rgb = np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)])
        assert np.sum(np.all(np.abs(pixels - rgb) < 12, axis=-1)) > 20, color
