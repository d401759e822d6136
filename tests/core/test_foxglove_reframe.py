"""The PoseArray views Foxglove's 3D panel draws, cut from the particle cloud's and the goals' CDR bytes: exactly
what rclpy would serialize for the same poses, for every header length (the padding before the first pose moves
with it), and a clear error for bytes that are not such a message."""

from __future__ import annotations

import random

import pytest
from geometry_msgs.msg import Pose, PoseArray, PoseStamped
from nav2_msgs.msg import Particle, ParticleCloud
from nav_msgs.msg import Goals
from rclpy.serialization import deserialize_message, serialize_message

from tb4.foxglove.reframe import CdrError, goals_to_pose_array, particle_cloud_to_pose_array

pytestmark = pytest.mark.core

FRAMES = ["", "m", "ma", "map", "mapx", "a_frame_of_eleven"]  # frame_id lengths 1..18 with the NUL: every padding


def _pose(rng: random.Random) -> Pose:
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (rng.uniform(-50, 50) for _ in range(3))
    pose.orientation.z, pose.orientation.w = rng.uniform(-1, 1), rng.uniform(-1, 1)
    return pose


def _same_wire(data: bytes, expected: PoseArray) -> None:
    """`data` carries `expected`: it decodes to it and has the length rclpy's serialization has (CDR's padding
    bytes are not compared: rclpy leaves them as it finds them)."""
    assert deserialize_message(data, PoseArray) == expected
    assert len(data) == len(serialize_message(expected))


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("count", [0, 1, 7])
def test_a_particle_cloud_becomes_the_pose_array_of_its_particles(frame: str, count: int) -> None:
    rng = random.Random(count * 31 + len(frame))
    cloud = ParticleCloud()
    cloud.header.frame_id = frame
    cloud.header.stamp.sec, cloud.header.stamp.nanosec = 1234, 567_000_000
    cloud.particles = [Particle(pose=_pose(rng), weight=rng.random()) for _ in range(count)]
    _same_wire(
        particle_cloud_to_pose_array(serialize_message(cloud)),
        PoseArray(header=cloud.header, poses=[p.pose for p in cloud.particles]),
    )


@pytest.mark.parametrize("frame", FRAMES)
@pytest.mark.parametrize("count", [0, 1, 5])
def test_goals_become_the_pose_array_of_their_poses_whatever_their_own_headers(frame: str, count: int) -> None:
    rng = random.Random(count * 17 + len(frame))
    goals = Goals()
    goals.header.frame_id = frame
    goals.header.stamp.sec = 99
    for k in range(count):
        goal = PoseStamped(pose=_pose(rng))
        goal.header.frame_id = FRAMES[k % len(FRAMES)]  # each goal's own header shifts the next pose's offset
        goal.header.stamp.nanosec = k
        goals.goals.append(goal)
    _same_wire(
        goals_to_pose_array(serialize_message(goals)),
        PoseArray(header=goals.header, poses=[g.pose for g in goals.goals]),
    )


def test_a_large_cloud_is_cut_in_one_slice() -> None:
    rng = random.Random(5)
    cloud = ParticleCloud()
    cloud.header.frame_id = "map"
    cloud.particles = [Particle(pose=_pose(rng), weight=1.0 / 5000) for _ in range(5000)]
    out = particle_cloud_to_pose_array(serialize_message(cloud))
    assert deserialize_message(out, PoseArray).poses == [p.pose for p in cloud.particles]


def _cloud_bytes(count: int) -> bytes:
    cloud = ParticleCloud()
    cloud.header.frame_id = "map"
    cloud.particles = [Particle() for _ in range(count)]
    return serialize_message(cloud)


@pytest.mark.parametrize(
    ("data", "says"),
    [
        (b"", "not plain CDR"),
        (b"\x00\x03\x00\x00" + bytes(40), "not plain CDR"),  # a representation this cannot read (XCDR2)
        (_cloud_bytes(3)[:30], "do not fit"),  # cut short in the particles
        (_cloud_bytes(0)[:14], "frame_id length"),  # cut short in the header
        (_cloud_bytes(0)[:12] + b"\xff\xff\xff\x7f" + bytes(8), "runs past the end"),  # a frame_id longer than all
        (_cloud_bytes(0)[:-4] + b"\xff\xff\xff\xff", "do not fit"),  # four billion particles claimed
    ],
    # named, not shown: serialized padding bytes may differ between processes, and pytest-xdist's workers must
    # collect the same test ids
    ids=["empty", "xcdr2", "cut-in-particles", "cut-in-header", "frame-id-too-long", "four-billion-particles"],
)
def test_bytes_that_are_not_such_a_message_raise_a_cdr_error(data: bytes, says: str) -> None:
    with pytest.raises(CdrError, match=says):
        particle_cloud_to_pose_array(data)
    with pytest.raises(CdrError):
        goals_to_pose_array(data)
