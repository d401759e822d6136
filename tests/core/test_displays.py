"""The Foxglove layout and the RViz config we ship (tb4.displays) name only topics that are there: the channels
`tb4 sim --foxglove` serves, the topics the simulator publishes or listens to; and the guide lists every display."""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from tb4.displays import FOXGLOVE_LAYOUT, RVIZ_CONFIG
from tb4.foxglove.live import DERIVED_TOPICS, SERVED_TOPICS

pytestmark = pytest.mark.core

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guides" / "foxglove.md"
CHANNELS = {f"/{topic.lstrip('/')}" for topic, _type, _qos in SERVED_TOPICS} | {
    f"/{derived}" for derived, _type, _cut in DERIVED_TOPICS.values()
}
SIMULATOR_INPUTS = {"goal_pose", "initialpose"}  # RViz's goal and pose-estimate tools publish these


def _layout() -> dict[str, Any]:
    return dict(json.loads(FOXGLOVE_LAYOUT.read_text(encoding="utf-8")))


def _panel_ids(node: Any) -> Iterator[str]:
    if isinstance(node, str):
        yield node
    else:
        yield from _panel_ids(node["first"])
        yield from _panel_ids(node["second"])


def test_the_layout_places_every_panel_it_configures() -> None:
    layout = _layout()
    assert sorted(_panel_ids(layout["layout"])) == sorted(layout["configById"])


def test_every_topic_the_layout_shows_is_a_channel_we_serve() -> None:
    layout = _layout()
    shown = set()
    for panel_id, config in layout["configById"].items():
        if panel_id.startswith("3D!"):
            shown |= {topic for topic, settings in config["topics"].items() if settings.get("visible")}
        for path in [p["value"] for p in config.get("paths", [])] + [config.get("path"), config.get("topicPath")]:
            if path:
                shown.add(re.match(r"(/[\w/]+?)(\.|$)", path).group(1))  # type: ignore[union-attr]
    assert shown and shown <= CHANNELS, sorted(shown - CHANNELS)
    three_d = next(config for panel_id, config in layout["configById"].items() if panel_id.startswith("3D!"))
    for topic in ("/map", "/global_costmap/costmap", "/local_costmap/costmap", "/scan", "/plan"):
        assert three_d["topics"][topic]["visible"], topic
    for topic in ("/particle_cloud/poses", "/goals/poses", "/amcl_pose"):
        assert three_d["topics"][topic]["visible"], topic


def _rviz() -> dict[str, Any]:
    return dict(yaml.safe_load(RVIZ_CONFIG.read_text(encoding="utf-8")))


def _displays(displays: list[dict[str, Any]]) -> Iterator[dict[str, Any]]:
    for display in displays:
        yield display
        yield from _displays(display.get("Displays", []))


def test_the_rviz_config_shows_each_of_our_topics_with_a_matching_qos() -> None:
    manager = _rviz()["Visualization Manager"]
    assert manager["Global Options"]["Fixed Frame"] == "map"
    served = {topic.lstrip("/") for topic, _type, _qos in SERVED_TOPICS}
    latched = {topic for topic, _type, qos in SERVED_TOPICS if qos == "latched"}
    by_topic = {}
    for display in _displays(manager["Displays"]):
        topic = display.get("Topic")
        if topic is None:
            continue
        assert topic["Value"] in served | SIMULATOR_INPUTS, display["Name"]
        # a transient-local reader gets a latched topic's last message; a volatile topic has no such writer
        wants_latched = topic["Durability Policy"] == "Transient Local"
        assert wants_latched == (topic["Value"] in latched), display["Name"]
        by_topic[topic["Value"]] = display["Class"]
    assert by_topic == {
        "map": "rviz_default_plugins/Map",
        "global_costmap/costmap": "rviz_default_plugins/Map",
        "local_costmap/costmap": "rviz_default_plugins/Map",
        "scan": "rviz_default_plugins/LaserScan",
        "odom": "rviz_default_plugins/Odometry",
        "plan": "rviz_default_plugins/Path",
        "particle_cloud": "nav2_rviz_plugins/ParticleCloud",
        "amcl_pose": "rviz_default_plugins/PoseWithCovariance",
        "goal_pose": "rviz_default_plugins/Pose",
    }
    assert any(d["Class"] == "rviz_default_plugins/TF" for d in _displays(manager["Displays"]))
    tools = {tool["Class"]: tool.get("Topic", {}).get("Value") for tool in manager["Tools"]}
    assert tools["rviz_default_plugins/SetInitialPose"] == "initialpose"
    assert tools["rviz_default_plugins/SetGoal"] == "goal_pose"


def test_the_guide_lists_every_rviz_display_and_the_layout() -> None:
    guide = GUIDE.read_text(encoding="utf-8")
    for display in _displays(_rviz()["Visualization Manager"]["Displays"]):
        assert f"**{display['Name']}**" in guide, display["Name"]
    assert "foxglove_layout.json" in guide and "turtlebot4.rviz" in guide
