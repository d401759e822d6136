"""The Create 3 API as users script it: the TurtleBot 4 manual's first node (button -> light ring) with
`tb4 press`, and our bump-and-go tutorial with `tb4 run`."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")

from tb4.processes import tb4_command  # noqa: E402
from tb4.tutorials import bump_and_go  # noqa: E402

from .tutorial_runs import record_of, results, run_json  # noqa: E402

PROGRAM = Path(__file__).parent / "programs" / "first_node.py"


def test_first_node_toggles_the_lightring_on_button_1(start_simulator, start_process, ros) -> None:
    from irobot_create_msgs.msg import LightringLeds

    start_simulator("--rate", "2", "--world", "depot")
    node = start_process([sys.executable, str(PROGRAM)], name="first_node")
    assert node.wait_for_output("first node ready", timeout=60), node.output()
    ring = ros.latest(LightringLeds, "tb4_sim/lightring")
    ros.wait_for(ring, what="the light ring")

    def colours(m) -> set[tuple[int, int, int]]:
        return {(c.red, c.green, c.blue) for c in m.leds}

    for expected, text in (({(255, 255, 255)}, "lights on"), ({(0, 0, 0)}, "lights off")):
        press = start_process(tb4_command("press", "1"), name="press")
        assert press.popen.wait(30) == 0, press.output()
        assert node.wait_for_output(text, timeout=30), node.output()
        msg = ros.wait_for(ring, lambda m, e=expected: m.override_system and colours(m) == e, what=text)
        assert colours(msg) == expected
    press = start_process(tb4_command("press", "2"), name="press2")  # another button: nothing happens
    assert press.popen.wait(30) == 0
    assert node.output().count("lights") == 2


def test_bump_and_go_tutorial(tmp_path: Path) -> None:
    code, events, stderr = run_json(["bump_and_go"], tmp_path)
    assert code == 0, (events[-3:], stderr[-2000:])
    record = record_of(events)
    assert record["summary"]["bumps"] >= bump_and_go.BUMPS
    assert results(record, "undock") == ["succeeded"]
    assert results(record, "rotate_angle") == ["succeeded"] * bump_and_go.BUMPS
    assert results(record, "audio_note_sequence") == ["succeeded"]
    rings = [e for e in record["events"] if e["type"] == "lightring"]
    assert any(e["override"] and e["leds"][0] == [255, 0, 0] for e in rings)  # red on each bump
    assert rings[-1]["override"] is False  # handed back to the robot at the end
