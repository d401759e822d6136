"""The QoS profiles the simulator and the viewer share, so a publisher and its subscribers always match; the one
QoS of every request and reply queue of ours (services and the services inside actions); and whether a writer can
serve a reader."""

from __future__ import annotations

from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["ACTION_STATUS", "LATCHED", "LATEST", "SENSOR", "REQUESTS", "REQUEST_DEPTH", "serves"]

#: What map_server and tf2 use for data sent once (map, tf_static, the global costmap, amcl_pose): a subscriber
#: that joins later still gets the last message.
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
#: For reading an action's status topic from outside the action's client: rcl_action publishes it reliable and
#: transient-local (each message lists every goal the server still tracks), so a reader whose writer matched it late
#: still gets the latest list; volatile (rclpy's default), such a reader missed whole goals. A few deep: a burst of
#: updates is each seen.
ACTION_STATUS = QoSProfile(
    depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
)
#: Reliable, newest message only: for a watcher that never wants a backlog.
LATEST = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: Best effort, newest message only: matches reliable and best-effort publishers alike.
SENSOR = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT)

#: Requests or replies a reader of ours keeps before DDS overwrites the oldest one not yet taken.
REQUEST_DEPTH = 1000
#: rclpy's services default (reliable, volatile) with a deep queue, for every service server, service client and
#: action server and client of ours. DDS keeps only `depth` unread samples per reader and overwrites the oldest one:
#: with rclpy's 10, a server whose executor took requests more slowly than a burst brought them silently lost
#: requests (the client waited for a goal response that could never come), and a client that took its replies
#: more slowly lost replies the same way. rclpy takes one request (or reply) per executor wake-up, so a burst, a
#: busy callback or a loaded machine is enough. A deeper queue costs nothing until it fills.
REQUESTS = QoSProfile(
    depth=REQUEST_DEPTH,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


def serves(writer_qos: Any, reader_qos: Any) -> bool:
    """Whether a writer with `writer_qos` can serve a reader with `reader_qos`, by the two policies our topics'
    endpoints differ in: a reliable reader takes no best-effort writer, a transient-local one no volatile writer.
    (rclpy's qos_check_compatible takes a local profile's unset deadline for a set one against the graph's infinite
    one.)

    Args:
        writer_qos: the writer's profile (a QoSProfile, or a graph entry's `qos_profile`).
        reader_qos: the reader's profile, likewise.

    Returns:
        True if DDS matches the two.
    """
    if (
        reader_qos.reliability != ReliabilityPolicy.BEST_EFFORT
        and writer_qos.reliability == ReliabilityPolicy.BEST_EFFORT
    ):
        return False
    volatile = writer_qos.durability in (DurabilityPolicy.VOLATILE, DurabilityPolicy.SYSTEM_DEFAULT)
    return not (reader_qos.durability == DurabilityPolicy.TRANSIENT_LOCAL and volatile)
