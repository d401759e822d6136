"""PoseArray views of two of our topics, cut from their CDR bytes: Foxglove's 3D panel draws geometry_msgs/PoseArray
but neither nav2_msgs/ParticleCloud nor nav_msgs/Goals.

Each function reads only offsets and lengths (the headers' strings, the sequences' counts) and copies the poses'
bytes as they are: no message object is built, so a cloud of thousands of particles costs one NumPy slice. Both
messages start with a std_msgs/Header, as PoseArray does, so the header's bytes and the padding before the first pose
carry over unchanged. Input that is not plain CDR of the expected type raises CdrError.
"""

from __future__ import annotations

import struct

import numpy as np

__all__ = ["CdrError", "particle_cloud_to_pose_array", "goals_to_pose_array", "POSE_SIZE"]

ENCAPSULATION = 4  # bytes before the data: representation id (2) and options (2)
POSE_SIZE = 56  # geometry_msgs/Pose: a Point and a Quaternion, 7 float64
PARTICLE_SIZE = 64  # nav2_msgs/Particle: a Pose and its float64 weight
_STAMP = 8  # builtin_interfaces/Time: int32 sec, uint32 nanosec
_PLAIN_CDR = {0: ">", 1: "<"}  # CDR_BE, CDR_LE (the representation id's second byte)


class CdrError(ValueError):
    """The bytes are not plain CDR of the message type a function reads."""


def _endianness(data: bytes) -> str:
    if len(data) < ENCAPSULATION or data[0] != 0 or data[1] not in _PLAIN_CDR:
        raise CdrError(f"not plain CDR (encapsulation {bytes(data[:ENCAPSULATION]).hex() or 'missing'})")
    return _PLAIN_CDR[data[1]]


def _align(offset: int, size: int) -> int:
    """`offset` moved on to the next multiple of `size`, counted from the end of the encapsulation header."""
    return offset + (-(offset - ENCAPSULATION)) % size


def _uint32(data: bytes, offset: int, endian: str, what: str) -> int:
    if offset + 4 > len(data):
        raise CdrError(f"message ends before its {what} (at byte {offset} of {len(data)})")
    return int(struct.unpack_from(endian + "I", data, offset)[0])


def _after_header(data: bytes, offset: int, endian: str) -> int:
    """The offset just past a std_msgs/Header (stamp, then frame_id: length with its NUL, then the bytes)."""
    offset = _align(offset, 4) + _STAMP
    length = _uint32(data, offset, endian, "frame_id length")
    offset += 4 + length
    if offset > len(data):
        raise CdrError(f"frame_id of {length} bytes runs past the end of the message ({len(data)} bytes)")
    return offset


def _count(data: bytes, offset: int, endian: str, element_size: int, what: str) -> tuple[int, int]:
    """A sequence's length and the offset after it, checked against the bytes left (a corrupt count must not make
    anyone allocate or loop for billions of elements)."""
    offset = _align(offset, 4)
    count = _uint32(data, offset, endian, f"{what} count")
    offset += 4
    if count * element_size > len(data) - offset:
        raise CdrError(f"{count} {what} do not fit in the {len(data) - offset} bytes left")
    return count, offset


def _pose_array(data: bytes, prefix_end: int, count: int, poses: bytes) -> bytes:
    """PoseArray bytes: the encapsulation (options cleared: no trailing padding is claimed), the header and count
    as read, the padding up to 8-byte alignment, then the poses."""
    head = bytes(data[:2]) + b"\0\0" + bytes(data[ENCAPSULATION:prefix_end])
    if count == 0:
        return head
    padding = _align(prefix_end, 8) - prefix_end
    return head + b"\0" * padding + poses


def particle_cloud_to_pose_array(data: bytes) -> bytes:
    """A serialized nav2_msgs/ParticleCloud as a serialized geometry_msgs/PoseArray (the weights dropped).

    Args:
        data: the ParticleCloud's CDR bytes, as a raw subscription receives them.

    Returns:
        The PoseArray's CDR bytes: the same header, one pose per particle, in order.

    Raises:
        CdrError: the bytes are not a plain-CDR ParticleCloud (too short, a bad length or count).
    """
    endian = _endianness(data)
    offset = _after_header(data, ENCAPSULATION, endian)
    count, offset = _count(data, offset, endian, PARTICLE_SIZE, "particles")
    if count == 0:
        return _pose_array(data, offset, 0, b"")
    start = _align(offset, 8)
    if start + count * PARTICLE_SIZE > len(data):
        raise CdrError(f"{count} particles do not fit in the message ({len(data)} bytes)")
    particles = np.frombuffer(data, dtype=np.uint8, count=count * PARTICLE_SIZE, offset=start)
    return _pose_array(data, offset, count, particles.reshape(count, PARTICLE_SIZE)[:, :POSE_SIZE].tobytes())


def goals_to_pose_array(data: bytes) -> bytes:
    """A serialized nav_msgs/Goals as a serialized geometry_msgs/PoseArray in the Goals' header frame.

    Each goal's own header is dropped: the simulator stamps every goal in the frame of the Goals' header (`map`).

    Args:
        data: the Goals' CDR bytes, as a raw subscription receives them.

    Returns:
        The PoseArray's CDR bytes: the Goals' header, then each goal's pose, in order.

    Raises:
        CdrError: the bytes are not a plain-CDR Goals (too short, a bad length or count).
    """
    endian = _endianness(data)
    offset = _after_header(data, ENCAPSULATION, endian)
    smallest = _STAMP + 4 + POSE_SIZE  # a PoseStamped with an empty frame_id still has its stamp, length and pose
    count, offset = _count(data, offset, endian, smallest, "goals")
    prefix_end = offset
    poses: list[bytes] = []
    for _ in range(count):
        offset = _align(_after_header(data, offset, endian), 8)
        if offset + POSE_SIZE > len(data):
            raise CdrError(f"goal {len(poses)} runs past the end of the message ({len(data)} bytes)")
        poses.append(bytes(data[offset : offset + POSE_SIZE]))
        offset += POSE_SIZE
    return _pose_array(data, prefix_end, count, b"".join(poses))
