"""A recording holds every message published on its reliable topics, or says which it missed.

Over DDS: `tb4 sim --record` with a client that sends initial poses and goals, its MCAP compared with what the
client sent and with what the simulator counted as published (the run record's `published`), idle and with one core
kept busy; an initial pose sent before any reader matched its writer, named as missed in a warning line. In this
process: a writer the recorder never matches, reported against its publisher's count; a message lost before the
recorder matched a writer, found from the writer's sequence numbers alone; the first messages of a writer present
at the start, lost on the way, named as missed when its first message came after the start; the ledger's counts and
a complete recording of a burst; a latched goal sent just before the end, delivered before the recording closes.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from geometry_msgs.msg import PoseWithCovarianceStamped
from irobot_create_msgs.action import Undock
from mcap.reader import make_reader
from nav2_msgs.action import NavigateToPose
from nav_msgs.msg import Goals
from nav_msgs.msg import Path as PathMsg
from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from tf2_msgs.msg import TFMessage

from tb4.core.waits import wait_until
from tb4.runner.mcap_record import METADATA_NAME, McapRecorder, PublicationLedger, recorded_topics

from .rosclient import RosClient, navigate_to_pose_goal

pytestmark = pytest.mark.dds

SUCCEEDED = 4
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
GOALS = ((-3.0, 0.0), (-3.0, -3.0))  # warehouse: two short drives from the dock (nav_through_poses' first two)
# one core kept busy for at most this many wall seconds (ended by PID at the test's end before that)
BUSY_LOOP = "import time\nend = time.monotonic() + 150.0\nwhile time.monotonic() < end:\n    pass\n"
NAMESPACE = "recording_check"  # the in-process tests' topics: apart from any simulator's


def _mcap_counts(path: Path) -> tuple[dict[str, int], dict[str, str]]:
    """Messages per topic in an MCAP file, and its tb4_recording metadata (each value JSON)."""
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {
            channel.topic: summary.statistics.channel_message_counts.get(cid, 0)
            for cid, channel in summary.channels.items()
        }
        metadata = {record.name: dict(record.metadata) for record in reader.iter_metadata()}
    return counts, metadata.get(METADATA_NAME, {})


def _initial_pose(x: float = 0.0, y: float = 0.0) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "map"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.w = 1.0
    msg.pose.covariance[0] = msg.pose.covariance[7] = 0.05
    msg.pose.covariance[35] = 0.02
    return msg


def _matched_by_every_reader(publisher: Any, node: Node, readers: int) -> None:
    """Wait until `publisher` has matched at least `readers` readers and every one the graph shows: a volatile
    message sent before its writer matched a reader never reaches that reader."""
    topic = publisher.topic_name
    wait_until(
        lambda: publisher.get_subscription_count() >= max(readers, node.count_subscribers(topic)),
        30.0,
        f"{readers} readers of {topic} matched",
    )


def _published(record: dict[str, Any], topic: str) -> int:
    """Messages the simulator counted as sent (or, for initialpose, taken) on `topic`: each writer's last number."""
    return sum(record["summary"]["published"].get(topic, {}).values())


@pytest.mark.parametrize("load", [False, True], ids=["idle", "one_core_busy"])
def test_a_recording_holds_every_message_published_on_its_reliable_topics(
    start_simulator, start_process, ros: RosClient, tmp_path: Path, load: bool
) -> None:
    if load:
        start_process([sys.executable, "-c", BUSY_LOOP], name="busy_loop")
    mcap, record_path = tmp_path / "run.mcap", tmp_path / "run.json"
    sim = start_simulator(
        "--rate", "max", "--hold", "--world", "warehouse", "--record", str(mcap), "--record-run", str(record_path)
    )
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    initial = ros.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
    _matched_by_every_reader(initial, ros.node, readers=2)  # amcl's and the recorder's
    initial.publish(_initial_pose(1.0, 0.0))
    initial.publish(_initial_pose())
    initial_poses = 2
    ros.wait_for(amcl, lambda m: abs(m.pose.pose.position.x) < 0.3, what="amcl_pose at the second initial pose")
    assert ros.action(Undock, "undock", Undock.Goal())[0] == SUCCEEDED
    goals = 0
    for x, y in GOALS:
        status, _ = ros.action(NavigateToPose, "navigate_to_pose", navigate_to_pose_goal(x, y), timeout=120.0)
        goals += 1
        assert status == SUCCEEDED, (x, y, status)
    assert sim.stop(timeout=30.0) == 0, sim.output()[-3000:]

    assert "warning: the recording" not in sim.output(), sim.output()[-3000:]
    record = json.loads(record_path.read_text())
    counts, metadata = _mcap_counts(mcap)
    # what this test sent itself
    assert counts["/initialpose"] == initial_poses == _published(record, "/initialpose")
    assert counts["/goals"] == goals == _published(record, "/goals")
    assert counts["/map"] == counts["/tf_static"] == 1
    # what the simulator counted as sent, every reliable topic: all of it is in the file
    reliable = [topic for topic, kind in recorded_topics("").items() if kind != "sensor"]
    assert {topic: counts[topic] for topic in reliable} == {topic: _published(record, topic) for topic in reliable}
    assert all(counts[topic] > 0 for topic in ("/plan", "/amcl_pose", "/tf", "/clock"))
    # and the recording says so itself: in the run record and in the file
    report = record["summary"]["recording"]
    assert report["complete"] is True and report["missed"] == {}, report
    assert report["checked"] == "publisher counts and sequence numbers"
    assert json.loads(metadata["complete"]) is True and json.loads(metadata["missed"]) == {}
    assert set(report["dropped_best_effort"]) <= {"/odom", "/scan", "/battery_state", "/dock_status", "/ground_truth"}


def test_an_initial_pose_sent_before_its_writer_matched_the_recorder_is_named_as_missed(
    start_simulator, ros: RosClient, tmp_path: Path
) -> None:
    mcap, record_path = tmp_path / "run.mcap", tmp_path / "run.json"
    sim = start_simulator(
        "--rate", "max", "--hold", "--world", "warehouse", "--record", str(mcap), "--record-run", str(record_path)
    )
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    # the first message of a writer in a new participant, sent before discovery: no reader can ever receive it
    late = RosClient("late_client")
    try:
        initial = late.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        initial.publish(_initial_pose(1.0, 0.0))
        if initial.get_subscription_count() != 0:
            pytest.skip("the new participant had matched a reader before its first message")
        _matched_by_every_reader(initial, late.node, readers=2)
        initial.publish(_initial_pose())
        ros.wait_for(amcl, lambda m: abs(m.pose.pose.position.x) < 0.3, what="amcl_pose at the initial pose")
    finally:
        late.close()
    assert sim.stop(timeout=30.0) == 0, sim.output()[-3000:]

    warning = [line for line in sim.output().splitlines() if "tb4 sim: warning: the recording" in line]
    assert warning and "/initialpose 1 of 2" in warning[0], sim.output()[-3000:]
    report = json.loads(record_path.read_text())["summary"]["recording"]
    assert report["complete"] is False and report["missed"] == {"/initialpose": 1}, report
    counts, metadata = _mcap_counts(mcap)
    assert counts["/initialpose"] == 1 and json.loads(metadata["missed"]) == {"/initialpose": 1}


class _CountedNode(Node):
    """The class PublicationLedger.counting watches here (the simulator's is SimNode)."""


@pytest.fixture
def context() -> Iterator[Any]:
    """An rclpy context of the test's own for its publishing nodes."""
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


def _counted_publisher(
    context: Any, node_name: str, msg_type: Any, topic: str, qos: Any
) -> tuple[PublicationLedger, Node, Any]:
    """A node of this process with one publisher on NAMESPACE's `topic`, counted by a ledger as the simulator's are.

    Returns:
        (the ledger, the node, the publisher).
    """
    ledger = PublicationLedger(f"/{NAMESPACE}")
    with ledger.counting(_CountedNode):
        node = _CountedNode(node_name, namespace=NAMESPACE, context=context)
        publisher = node.create_publisher(msg_type, topic, qos)
    return ledger, node, publisher


@pytest.fixture
def recorder(tmp_path: Path) -> Iterator[McapRecorder]:
    """A recorder of NAMESPACE's topics into tmp_path/run.mcap, closed at the end if the test did not."""
    recorder = McapRecorder(tmp_path / "run.mcap", NAMESPACE)
    recorder.wait_for_startup_topics(1.0)  # nothing to wait for here: it takes the writers present as the start
    yield recorder
    recorder.close(timeout=0.0)


def test_a_writer_the_recorder_never_matches_is_reported_against_its_publishers_count(
    context: Any, recorder: McapRecorder, tmp_path: Path
) -> None:
    ledger = PublicationLedger(f"/{NAMESPACE}")
    with ledger.counting(_CountedNode):
        node = _CountedNode("volatile_goals", namespace=NAMESPACE, context=context)
        # volatile: the recorder reads `goals` transient local, which a volatile writer can never serve (and the
        # incompatible QoS need not be logged)
        quiet = PublisherEventCallbacks(use_default_callbacks=False)
        publisher = node.create_publisher(Goals, "goals", 10, event_callbacks=quiet)
    try:
        publisher.publish(Goals())
        published = ledger.snapshot()
        assert list(published) == [f"/{NAMESPACE}/goals"] and list(published[f"/{NAMESPACE}/goals"].values()) == [1]
        report = recorder.close(published, timeout=1.0)
    finally:
        node.destroy_node()
    assert report.missed == {f"/{NAMESPACE}/goals": 1} and not report.complete and report.against_publisher
    assert report.warning() is not None and f"/{NAMESPACE}/goals 1 of 1" in report.warning()
    _, metadata = _mcap_counts(tmp_path / "run.mcap")
    assert json.loads(metadata["complete"]) is False


def test_a_message_sent_before_a_new_writer_matched_is_found_from_its_sequence_numbers(
    context: Any, recorder: McapRecorder
) -> None:
    node = Node("late_writer", namespace=NAMESPACE, context=context)
    topic = f"/{NAMESPACE}/initialpose"
    try:
        publisher = node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        publisher.publish(_initial_pose())  # a new participant's first message, sent before discovery
        if publisher.get_subscription_count() != 0:
            pytest.skip("the new participant had matched the recorder before its first message")
        _matched_by_every_reader(publisher, node, readers=1)
        publisher.publish(_initial_pose())
        wait_until(lambda: recorder.counts[topic] == 1, 10.0, "the second initial pose recorded")
        report = recorder.close()  # no publisher counts: the writer's numbers alone (it started at 2)
    finally:
        node.destroy_node()
    assert report.missed == {topic: 1} and not report.against_publisher
    assert report.recorded[topic] == 1


def _broken_first_sent(first_sent: dict[str, dict[str, int]]) -> dict[str, Any]:
    """The ledger's first-send times as a hand-edited or damaged run record may hold them: not numbers, not maps."""
    broken: dict[str, Any] = {
        topic: {key: str(sent) for key, sent in writers.items()} for topic, writers in first_sent.items()
    }
    broken.update({f"/{NAMESPACE}/tf": ["x"], f"/{NAMESPACE}/goals": None, f"/{NAMESPACE}/map": {"k": True}})
    return broken


@pytest.mark.parametrize(
    ("first_sent_of", "missed"),
    [(PublicationLedger.first_sent, 2), (lambda ledger: _broken_first_sent(ledger.first_sent()), 0)],
    ids=["from-the-ledger", "broken"],
)
def test_the_first_messages_of_a_writer_that_began_after_the_recording_are_named_as_missed(
    context: Any, tmp_path: Path, first_sent_of: Any, missed: int
) -> None:
    """With broken first-send times the report falls back to the rule without them (a writer present at the start
    owes what it sent from the first message received on): no exception, nothing made up."""
    # the simulator's plan writer: made at its start, sending on each goal
    ledger, node, plan = _counted_publisher(context, "planner", PathMsg, "plan", 1)
    topic = f"/{NAMESPACE}/plan"
    recorder = McapRecorder(tmp_path / "run.mcap", NAMESPACE)
    try:
        recorder.wait_for_startup_topics(10.0)  # the plan's writer is present and matched: the recording begins
        _matched_by_every_reader(plan, node, readers=1)
        # the writer's first two messages are lost on the way (on a starved machine, a depth-1 writer replaces a
        # message before the recorder takes it): the numbers received start at 3, no gap among them
        write, arrived = recorder._write, []

        def lossy(channel: int, name: str, data: Any, info: Any) -> None:
            arrived.append(name)
            if name != topic or arrived.count(topic) > 2:
                write(channel, name, data, info)

        recorder._write = lossy  # type: ignore[method-assign]
        for k in range(5):  # one at a time: none replaced in the writer's history of one
            plan.publish(PathMsg())
            wait_until(lambda k=k: arrived.count(topic) == k + 1, 10.0, f"plan {k + 1} taken by the recorder")
        report = recorder.close(ledger.snapshot(), first_sent=first_sent_of(ledger))
    finally:
        recorder.close(timeout=0.0)
        node.destroy_node()
    assert report.recorded[topic] == 3 and report.missed == ({topic: missed} if missed else {}), report
    if missed:
        assert report.warning() is not None and f"{topic} {missed} of 5" in report.warning()


def test_a_burst_checked_against_the_ledger_is_recorded_complete(context: Any, recorder: McapRecorder) -> None:
    ledger = PublicationLedger(f"/{NAMESPACE}")
    with ledger.counting(_CountedNode):
        node = _CountedNode("burst", namespace=NAMESPACE, context=context)
        tf = node.create_publisher(TFMessage, "tf", 100)  # the simulator's tf depth
        goals = node.create_publisher(Goals, "goals", LATCHED)
        untracked = node.create_publisher(TFMessage, "not_recorded", 10)
    topics = {f"/{NAMESPACE}/tf", f"/{NAMESPACE}/goals"}
    try:
        _matched_by_every_reader(tf, node, readers=1)
        _matched_by_every_reader(goals, node, readers=1)
        untracked.publish(TFMessage())
        for _ in range(100):
            tf.publish(TFMessage())
        for k in range(3):  # one goal at a time, as goals come
            goals.publish(Goals())
            wait_until(lambda k=k: recorder.counts[f"/{NAMESPACE}/goals"] == k + 1, 10.0, f"goal {k + 1} recorded")
        assert ledger.wait_for_delivery(10.0) == []
        published = ledger.snapshot()
        report = recorder.close(published)
    finally:
        node.destroy_node()
    assert set(published) == topics  # only the recorded topics are counted
    assert {topic: sum(writers.values()) for topic, writers in published.items()} == {
        f"/{NAMESPACE}/tf": 100,
        f"/{NAMESPACE}/goals": 3,
    }
    assert report.complete and report.against_publisher, report
    assert {topic: report.recorded[topic] for topic in topics} == {f"/{NAMESPACE}/tf": 100, f"/{NAMESPACE}/goals": 3}


def test_a_latched_goal_sent_just_before_the_end_is_delivered_before_the_recording_closes(
    context: Any, recorder: McapRecorder
) -> None:
    ledger, node, goals = _counted_publisher(context, "late_goals", Goals, "goals", LATCHED)
    try:
        goals.publish(Goals())  # its one message, sent before its writer has matched the recorder's reader
        # as in a run, this process knows of the recorder (the simulator has seen it since the start)
        wait_until(lambda: node.count_subscribers(goals.topic_name) >= 1, 10.0, "the recorder in the graph")
        assert ledger.wait_for_delivery(10.0) == []  # what the simulator does before its writers go
        report = recorder.close(ledger.snapshot())
    finally:
        node.destroy_node()
    assert report.complete and report.recorded[f"/{NAMESPACE}/goals"] == 1, report
