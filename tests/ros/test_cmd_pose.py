"""`tb4 pose` over real DDS: delivered to the simulator (confirmed on amcl_pose) or to a named subscriber,
without fixed waits or spurious warnings; a missing subscriber is a clear failure, never a hang."""

from __future__ import annotations

import math
import subprocess

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tb4.processes import tb4_command
from tb4.ros.convert import pose_to_tuple

pytestmark = pytest.mark.dds

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def tb4_pose(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run(tb4_command("pose", *args), capture_output=True, text=True, timeout=timeout)


def test_pose_reaches_the_simulator_and_a_named_subscriber(start_simulator, ros) -> None:
    # Truth localization: amcl_pose is then exactly the pose sent (a particle filter reports its particles' mean).
    # Held at real time: nothing here waits on simulated time (an initial pose is not a command that ends the hold),
    # and at --rate max the simulator would spend a core on the dock while the two `tb4 pose` processes start.
    start_simulator("--rate", "max", "--hold", "--world", "warehouse", "--localization", "truth")
    amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    done = tb4_pose("-2", "1", "west")
    assert done.returncode == 0, done.stderr
    assert "published initialpose (-2, 1) heading 90 deg" in done.stdout
    assert "acknowledged" not in done.stderr and done.stderr.strip() == ""
    msg = ros.wait_for(amcl, lambda m: abs(m.pose.pose.position.x + 2.0) < 0.01, what="amcl_pose at the new pose")
    x, y, yaw = pose_to_tuple(msg.pose.pose)
    assert (x, y) == pytest.approx((-2.0, 1.0), abs=0.01) and yaw == pytest.approx(math.pi / 2, abs=0.01)

    # a named subscriber (like the create_path tutorial) gets it too
    got: list = []
    ros.node.create_subscription(PoseWithCovarianceStamped, "initialpose", got.append, 10)
    done = tb4_pose("3", "-1", "--wait-for", "test_client")
    assert done.returncode == 0, done.stderr
    ros.wait_for(lambda: got or None, what="the pose at the named subscriber", timeout=10.0)
    assert got[-1].pose.pose.position.x == 3.0 and got[-1].header.frame_id == "map"


def test_no_subscriber_is_a_clear_failure(ros) -> None:
    done = tb4_pose("1", "2", "--timeout", "1")
    assert done.returncode == 1 and "nobody subscribes to 'initialpose' after 1 s" in done.stderr
    ros.node.create_subscription(PoseWithCovarianceStamped, "initialpose", lambda m: None, 10)
    done = tb4_pose("1", "2", "--wait-for", "someone_else", "--timeout", "1")
    assert done.returncode == 1 and "node 'someone_else'" in done.stderr


def test_a_pose_the_localizer_never_got_is_sent_again_until_it_reports_it(ros) -> None:
    """Discovery is per side: the localizer's reader can match tb4 pose's writer only after the pose went out,
    and a volatile sample sent before that never reaches it. Here a localizer that drops the first pose it gets
    stands in for that: tb4 pose must send it again and succeed, not wait out its timeout."""
    got: list[PoseWithCovarianceStamped] = []
    amcl = ros.node.create_publisher(PoseWithCovarianceStamped, "amcl_pose", LATCHED)

    def localizer(msg: PoseWithCovarianceStamped) -> None:
        got.append(msg)
        if len(got) >= 2:  # the first one is "lost"
            amcl.publish(msg)

    ros.node.create_subscription(PoseWithCovarianceStamped, "initialpose", localizer, 10)
    done = tb4_pose("1.5", "-2", "north", "--timeout", "8")
    assert done.returncode == 0, done.stderr
    assert len(got) >= 2 and pose_to_tuple(got[-1].pose.pose)[:2] == pytest.approx((1.5, -2.0))
