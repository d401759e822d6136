"""`tb4 run --record` checks its recording against what the simulator published, as a user runs it: the run record's
`summary.recording`, the MCAP's own `tb4_recording` metadata, and a warning line for whatever was missed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")

from mcap.reader import make_reader  # noqa: E402

from .tutorial_runs import record_of, run_json  # noqa: E402

# sent by the simulator after the recording began, or (initialpose) taken by it from the mission's writer
CHECKED = ("/goals", "/plan", "/amcl_pose", "/map", "/tf_static", "/initialpose")


def test_a_recorded_run_accounts_for_every_message_published_on_its_reliable_topics(tmp_path: Path) -> None:
    mcap = tmp_path / "run.mcap"
    code, events, stderr = run_json(["nav_to_pose", "--record", str(mcap)], tmp_path)
    assert code == 0, (events[-3:], stderr[-2000:])
    record = record_of(events)
    report = record["summary"]["recording"]
    assert report["checked"] == "publisher counts and sequence numbers" and report["path"] == str(mcap)
    with mcap.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {
            channel.topic: summary.statistics.channel_message_counts.get(cid, 0)
            for cid, channel in summary.channels.items()
        }
        metadata = {item.name: dict(item.metadata) for item in reader.iter_metadata()}["tb4_recording"]
    assert {key: json.loads(value) for key, value in metadata.items()} == report
    published = record["summary"]["published"]
    # every message sent is in the file or named as missed: none goes unsaid
    for topic in CHECKED:
        assert counts[topic] + report["missed"].get(topic, 0) == sum(published[topic].values()), (topic, report)
    assert counts["/goals"] >= 1 and counts["/map"] == counts["/tf_static"] == 1
    warnings = [e["text"] for e in events if e["event"] == "message" and "warning: the recording" in e["text"]]
    if report["missed"]:
        assert len(warnings) == 1 and all(f"{topic} {n} of" in warnings[0] for topic, n in report["missed"].items())
    else:
        assert warnings == [] and report["complete"] is True
