"""The QoS profiles the simulator and the viewer share, so a publisher and its subscribers always match."""

from __future__ import annotations

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

__all__ = ["LATCHED", "LATEST", "SENSOR"]

#: What map_server and tf2 use for data sent once (map, tf_static, the global costmap, amcl_pose): a subscriber
#: that joins later still gets the last message.
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
#: Reliable, newest message only: for a watcher that never wants a backlog.
LATEST = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE)
#: Best effort, newest message only: matches reliable and best-effort publishers alike.
SENSOR = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.BEST_EFFORT)
