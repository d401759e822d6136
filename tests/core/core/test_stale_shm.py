"""remove_stale_shm removes the Fast DDS files our processes left behind, and nothing a live participant uses.

Fast DDS reuses names: the next participant on a port takes over a dead one's files, under the port's named mutex
(a POSIX semaphore). These tests lay out such files in a directory of their own, semaphores included (real glibc
semaphores, as Fast DDS's sem_open makes them), and play the new owner's part at the moment that matters."""

from __future__ import annotations

import ctypes
import fcntl
import mmap
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tb4 import processes

pytestmark = pytest.mark.core

LIBC = ctypes.CDLL(None, use_errno=True)


def _shm_file(directory: Path, name: str, age: float = 60.0) -> Path:
    path = directory / name
    path.write_bytes(bytes(4096))
    os.utime(path, (time.time() - age, time.time() - age))
    return path


def _mapped(path: Path) -> mmap.mmap:
    with path.open("r+b") as handle:
        return mmap.mmap(handle.fileno(), 4096)


class Semaphore:
    """A port's named mutex as sem_open makes it (a 32-byte file holding a process-shared sem_t), mapped here."""

    def __init__(self, directory: Path, port: str, age: float = 60.0) -> None:
        self.path = directory / f"sem.{port}_mutex"
        self.path.write_bytes(bytes(32))
        with self.path.open("r+b") as handle:
            self._mapping = mmap.mmap(handle.fileno(), 32)
        self._cell = ctypes.c_char.from_buffer(self._mapping)
        self._address = ctypes.c_void_p(ctypes.addressof(self._cell))
        assert LIBC.sem_init(self._address, 1, 1) == 0
        os.utime(self.path, (time.time() - age, time.time() - age))
        self.inode = self.path.stat().st_ino

    def acquire(self) -> None:
        assert LIBC.sem_trywait(self._address) == 0, "the semaphore was not free"

    def release(self) -> None:
        assert LIBC.sem_post(self._address) == 0

    def is_free(self) -> bool:
        if LIBC.sem_trywait(self._address) != 0:
            return False
        self.release()
        return True

    def close(self) -> None:
        del self._cell
        self._mapping.close()


@pytest.fixture
def shm_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    monkeypatch.setattr(processes, "SHM_DIR", tmp_path)
    yield tmp_path


@pytest.fixture
def semaphores(shm_dir: Path) -> Iterator[dict[str, Semaphore]]:
    made: dict[str, Semaphore] = {}
    yield made
    for semaphore in made.values():
        semaphore.close()


def _dead_port(directory: Path, port: str, semaphores: dict[str, Semaphore]) -> list[Path]:
    """The files a participant killed while it listened on `port` leaves: the segment, its lock file, its mutex."""
    semaphores[port] = Semaphore(directory, port)
    return [_shm_file(directory, port), _shm_file(directory, f"{port}_el")]


def _after_the_scan(monkeypatch: pytest.MonkeyPatch, act) -> None:  # type: ignore[no-untyped-def]
    """Run `act` once the clean-up's scan of the processes is done, before it removes anything."""

    class Proc(type(Path())):  # type: ignore[misc]
        def iterdir(self):  # type: ignore[no-untyped-def]
            yield from super().iterdir()
            if str(self) == "/proc":
                act()

    monkeypatch.setattr(processes, "Path", Proc)


def test_leftovers_are_removed_and_files_in_use_or_just_made_are_kept(shm_dir: Path, semaphores) -> None:
    before = processes.shm_snapshot()
    gone = _dead_port(shm_dir, "fastrtps_port7990", semaphores)
    gone += [_shm_file(shm_dir, "fastdds_0123456789abcdef"), _shm_file(shm_dir, "fastdds_0123456789abcdef_el")]
    young = _shm_file(shm_dir, "fastrtps_port7991", age=0.0)  # its creator may not have mapped it yet
    served = _shm_file(shm_dir, "fastrtps_port7992")
    semaphores["fastrtps_port7992"] = Semaphore(shm_dir, "fastrtps_port7992")  # not mapped while its port serves
    locked = _shm_file(shm_dir, "fastrtps_port7993_el")
    semaphores["fastrtps_port7993"] = Semaphore(shm_dir, "fastrtps_port7993")
    mapping = _mapped(served)
    lock = os.open(locked, os.O_RDONLY)
    fcntl.flock(lock, fcntl.LOCK_EX)
    try:
        removed = processes.remove_stale_shm(before)
    finally:
        mapping.close()
        os.close(lock)
    assert removed == sorted(path.name for path in gone)
    assert all(path.exists() for path in (young, served, locked))
    # a port's mutex stays (an opener may wait on it), and the clean-up left it free
    assert all(semaphore.path.exists() and semaphore.is_free() for semaphore in semaphores.values())


def test_a_port_being_opened_is_left_whole(shm_dir: Path, semaphores) -> None:
    """A participant opening a port holds its mutex from its test of the old owner to its lock of a new lock file:
    the files may be the dead owner's still, but they are the new owner's to replace."""
    before = processes.shm_snapshot()
    files = _dead_port(shm_dir, "fastdds_port7995", semaphores)
    semaphores["fastdds_port7995"].acquire()  # the opener, inside Fast DDS's open_port
    try:
        assert processes.remove_stale_shm(before) == []
    finally:
        semaphores["fastdds_port7995"].release()
    assert all(path.exists() for path in files)
    assert processes.remove_stale_shm(before) == sorted(path.name for path in files)  # once it has let go


def test_a_port_taken_after_the_scan_keeps_its_lock_file_and_mutex(
    shm_dir: Path, semaphores, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Run 54 of the stress series: a script got nothing from the simulator while the simulator heard it, and it
    had started the moment other workers' fixtures cleaned up. A clean-up that listed a dead port removed, after
    its scan, files of the port a new participant had just taken (the same files, the same inodes): a listener
    left on a segment no writer opens any more, or a next opener that finds no owner and runs beside it."""
    before = processes.shm_snapshot()
    segment, lock_file = _dead_port(shm_dir, "fastdds_port7996", semaphores)
    mutex = semaphores["fastdds_port7996"]
    held: list[int] = []

    def take_over() -> None:  # the new owner opens the port: mutex, lock file, segment mapped, mutex let go
        mutex.acquire()
        handle = os.open(lock_file, os.O_RDONLY)
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        held.append(handle)
        mutex.release()

    _after_the_scan(monkeypatch, take_over)
    try:
        assert processes.remove_stale_shm(before) == []
        assert lock_file.exists() and lock_file.stat().st_ino == os.fstat(held[0]).st_ino
        assert segment.exists() and mutex.path.exists() and mutex.path.stat().st_ino == mutex.inode
    finally:
        for handle in held:
            os.close(handle)


def test_a_port_whose_mutex_is_taken_after_the_scan_keeps_its_files(
    shm_dir: Path, semaphores, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same race one step earlier: the new owner holds the port's mutex when the clean-up comes to it."""
    before = processes.shm_snapshot()
    files = _dead_port(shm_dir, "fastdds_port7997", semaphores)
    mutex = semaphores["fastdds_port7997"]
    _after_the_scan(monkeypatch, mutex.acquire)
    try:
        assert processes.remove_stale_shm(before) == []
    finally:
        mutex.release()
    assert all(path.exists() for path in files) and mutex.path.stat().st_ino == mutex.inode


def test_a_name_a_new_participant_takes_over_during_the_scan_is_kept(
    shm_dir: Path, semaphores, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Fast DDS replaces a dead port's segment under the same name; removed by name after the scan, the new
    participant's port went too. A live participant whose port file is removed hears nothing more from a writer
    that opens the port afterwards (matched, and no message), and the next participants log "Failed init_port
    ...: open_and_lock_file failed"."""
    before = processes.shm_snapshot()
    semaphores["fastrtps_port7994"] = Semaphore(shm_dir, "fastrtps_port7994")
    port = _shm_file(shm_dir, "fastrtps_port7994")  # a dead participant's port
    taken: list[mmap.mmap] = []

    def take_over() -> None:  # a new participant's port under the same name, mapped by it
        fresh = _shm_file(shm_dir, "fastrtps_port7994.new", age=0.0)
        taken.append(_mapped(fresh))
        fresh.replace(port)

    _after_the_scan(monkeypatch, take_over)
    try:
        processes.remove_stale_shm(before)
        assert port.exists(), "the new participant's port was removed"
    finally:
        for mapping in taken:
            mapping.close()


def test_a_port_without_a_mutex_file_is_left_to_fast_dds(shm_dir: Path) -> None:
    """Without the mutex file there is no lock to hold; the next opener creates one and resets the port itself."""
    before = processes.shm_snapshot()
    files = [_shm_file(shm_dir, "fastdds_port7998"), _shm_file(shm_dir, "fastdds_port7998_el")]
    assert processes.remove_stale_shm(before) == []
    assert all(path.exists() for path in files)


def test_a_mutex_file_that_is_no_semaphore_leaves_its_port_alone(shm_dir: Path) -> None:
    """A truncated or foreign "sem." file: no lock to take, so nothing of the port is removed, and no error."""
    before = processes.shm_snapshot()
    files = [_shm_file(shm_dir, "fastdds_port7999"), _shm_file(shm_dir, "fastdds_port7999_el")]
    for content in (b"", b"x" * 8):
        (shm_dir / "sem.fastdds_port7999_mutex").write_bytes(content)
        assert processes.remove_stale_shm(before) == []
        assert all(path.exists() for path in files)
