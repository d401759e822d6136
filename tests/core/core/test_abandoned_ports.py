"""free_abandoned_ports: a Fast DDS port segment created and never sized (its creator killed in between) is given a
size of 1, which releases Boost's openers waiting for a size, and removed; every other file is left alone."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from tb4 import processes


@pytest.fixture
def shm(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(processes, "SHM_DIR", tmp_path)
    return tmp_path


def test_an_empty_port_segment_is_removed_and_others_stay(shm: Path) -> None:
    (shm / "fastdds_port7000").touch()  # Kilted's Fast DDS 3
    (shm / "fastrtps_port7411").touch()  # Jazzy's Fast DDS 2.14
    (shm / "fastdds_port7412").write_bytes(b"\0" * 64)  # a live port: sized
    (shm / "fastdds_port7000_el").touch()  # lock files are empty by nature
    (shm / "sem.fastdds_port7000_mutex").touch()
    (shm / "fastdds_0123456789abcdef").touch()  # a participant's segment, not a port
    freed = processes.free_abandoned_ports(min_age=0.0)
    assert sorted(freed) == ["fastdds_port7000", "fastrtps_port7411"]
    assert sorted(p.name for p in shm.iterdir()) == [
        "fastdds_0123456789abcdef",
        "fastdds_port7000_el",
        "fastdds_port7412",
        "sem.fastdds_port7000_mutex",
    ]


def test_a_segment_just_created_is_left_to_its_creator(shm: Path) -> None:
    (shm / "fastdds_port7000").touch()  # its creator sizes it next
    assert processes.free_abandoned_ports(min_age=60.0) == []
    assert (shm / "fastdds_port7000").exists()


def test_an_opener_waiting_for_the_size_is_released(shm: Path) -> None:
    """Boost's opener polls the size of the segment it opened (fstat of its descriptor) until it is not 0; a size
    of 1 makes it give up (a corrupted segment) and Fast DDS creates the port anew."""
    port = shm / "fastdds_port7000"
    port.touch()
    handle = os.open(port, os.O_RDONLY)
    seen: list[int] = []

    def opener() -> None:
        while os.fstat(handle).st_size == 0 and len(seen) < 1:
            threading.Event().wait(0.01)
        seen.append(os.fstat(handle).st_size)

    waiting = threading.Thread(target=opener, daemon=True)
    waiting.start()
    try:
        assert processes.free_abandoned_ports(min_age=0.0) == ["fastdds_port7000"]
        waiting.join(5.0)
        assert seen == [1] and not port.exists()
    finally:
        seen.append(-1)  # ends the opener whatever happened
        os.close(handle)
