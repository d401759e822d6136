"""Starting and stopping our own ROS processes by PID, and cleaning up after Fast DDS.

Fast DDS keeps data in /dev/shm segments; a process killed hard leaves them behind. We remove only segments that
appeared while we ran and that no live process maps, holds open or locks (judged by the file, not its name, which
Fast DDS gives the next participant), and a port's files only under the port's own mutex, as Fast DDS's
participants take it, so concurrent users of the machine are safe.
"""

from __future__ import annotations

import contextlib
import ctypes
import faulthandler
import fcntl
import functools
import mmap
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, NoReturn

from tb4.core.waits import wait_until

__all__ = [
    "READY_LINE",
    "CONTROL_REPLY",
    "release_domain_id",
    "claim_domain_id",
    "ManagedProcess",
    "ros_environment",
    "shm_snapshot",
    "remove_stale_shm",
    "free_abandoned_ports",
    "abandoned_ports_watched",
    "ABANDONED_PORT_AGE",
    "clean_shm_after_exit",
    "SHM_DIR",
    "SHM_GRACE",
    "PARENT_ENV",
    "end_with_parent",
    "restore_stop_signals",
    "exit_now",
    "flush_output",
    "exit_within",
    "tb4_command",
]

#: what `tb4 sim` prints (and flushes) on standard output once it serves every interface: the readiness signal for
#: whoever starts it (tb4 run, the test kit, a user's own harness)
READY_LINE = "tb4 sim ready"
CONTROL_REPLY = "tb4 sim control:"  # the start of each reply of `tb4 sim --control` (tb4.ros.simulator.serve_control)

SHM_DIR = Path("/dev/shm")
_SHM_PREFIXES = ("fastrtps_", "fastdds_", "sem.fastrtps_", "sem.fastdds_")


def tb4_command(*args: str) -> list[str]:
    """The command line of `tb4 ARGS...` run by this interpreter (a child of ours: the same environment, whether or
    not the `tb4` script is on PATH)."""
    return [sys.executable, "-m", "tb4.cli.main", *args]


def ros_environment(domain_id: int | None = None, base: Mapping[str, str] | None = None) -> dict[str, str]:
    """An environment for a child ROS process: loopback discovery unless chosen explicitly, the given domain."""
    env = dict(os.environ if base is None else base)
    if "ROS_AUTOMATIC_DISCOVERY_RANGE" not in env and "ROS_LOCALHOST_ONLY" not in env:
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    if domain_id is not None:
        env["ROS_DOMAIN_ID"] = str(domain_id)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


_domain_locks: dict[int, IO[str]] = {}


def claim_domain_id(first: int = 10, last: int = 101) -> int:
    """A ROS_DOMAIN_ID no other run on this machine holds (an flock on a file per id, held until we exit)."""
    import random
    import tempfile

    lock_dir = Path(tempfile.gettempdir())
    candidates = list(range(first, last + 1))
    random.Random(os.getpid()).shuffle(candidates)
    for domain in candidates:
        handle = open(lock_dir / f"tb4-ros-domain-{domain}.lock", "w")  # noqa: SIM115 - held for the process life
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            handle.close()
            continue
        _domain_locks[domain] = handle
        return domain
    raise RuntimeError(f"no free ROS_DOMAIN_ID between {first} and {last} on this machine")


def release_domain_id(domain: int) -> None:
    """Give back a domain claim_domain_id gave this process (a test's simulator is done with it)."""
    handle = _domain_locks.pop(domain, None)
    if handle is not None:
        handle.close()


def shm_snapshot() -> set[str]:
    if not SHM_DIR.is_dir():
        return set()
    return {p.name for p in SHM_DIR.iterdir() if p.name.startswith(_SHM_PREFIXES)}


#: s: a Fast DDS file younger than this is left for a later call: its creator maps it (or locks it) just after
#: creating it, and a scan that reads that process in between would take it for a leftover.
SHM_GRACE = 2.0


def _shm_inodes_in_use() -> set[int]:
    """Inodes of the /dev/shm files some live process maps, holds open or holds a lock on (a Fast DDS "_el" file
    is a live participant's port or segment while its owner holds an flock on it)."""
    inodes: set[int] = set()
    prefix = f"{SHM_DIR}/"
    for proc in Path("/proc").iterdir():
        if not proc.name.isdigit():
            continue
        with contextlib.suppress(OSError):
            for line in (proc / "maps").read_text().splitlines():
                fields = line.split(maxsplit=5)
                if len(fields) == 6 and fields[5].startswith(prefix):
                    inodes.add(int(fields[4]))
        try:
            descriptors = list((proc / "fd").iterdir())
        except OSError:
            continue
        for fd in descriptors:
            try:  # one descriptor closed meanwhile must not hide the process's others
                if os.readlink(fd).startswith(prefix):
                    inodes.add(os.stat(fd).st_ino)
            except OSError:
                continue
    return inodes | _locked_shm_inodes()


def _locked_shm_inodes() -> set[int]:
    """Inodes of SHM_DIR's files under a lock (/proc/locks: "1: FLOCK ADVISORY WRITE PID MAJ:MIN:INODE 0 EOF")."""
    try:
        device = SHM_DIR.stat().st_dev
        text = Path("/proc/locks").read_text()
    except OSError:
        return set()
    inodes = set()
    for line in text.splitlines():
        for field in line.split():
            parts = field.split(":")
            if len(parts) == 3 and all(parts):
                with contextlib.suppress(ValueError):
                    if (int(parts[0], 16), int(parts[1], 16)) == (os.major(device), os.minor(device)):
                        inodes.add(int(parts[2]))
                break
    return inodes


def _owner_in_use(name: str, in_use: set[int]) -> bool:
    """Whether the participant segment a lock file ("_el") belongs to is in use: the lock file is neither mapped nor
    held open while its segment serves. (A port's files, mutex included, go through `_remove_dead_port`.)"""
    owner = name.removesuffix("_el")
    if owner == name:
        return False
    with contextlib.suppress(OSError):
        return (SHM_DIR / owner).stat().st_ino in in_use
    return False


def remove_stale_shm(before: set[str]) -> list[str]:
    """Remove Fast DDS shared-memory files created since `before` that nobody uses any more.

    Fast DDS gives a new participant the lowest free port and takes over the files a dead participant left under
    the same names, so a name is judged by the file it names when listed (its inode), and a name whose file changed
    before it is removed (a new owner's) is left alone. A port's files are removed only while holding the port's
    own lock, as Fast DDS's participants do (`_remove_dead_port`). A participant's data segments have names of
    their own, never reused.

    Args:
        before: the names from `shm_snapshot()` before the processes whose leftovers are removed were started.

    Returns:
        The names removed.
    """
    new = shm_snapshot() - before
    if not new:
        return []
    now = time.time()
    listed: dict[str, int] = {}
    for name in new:
        with contextlib.suppress(OSError):
            info = (SHM_DIR / name).stat()
            if now - info.st_mtime >= SHM_GRACE:
                listed[name] = info.st_ino
    if not listed:
        return []
    in_use = _shm_inodes_in_use()
    removed = []
    ports: dict[str, dict[str, int]] = {}
    for name, inode in sorted(listed.items()):
        port = _PORT_FILE.fullmatch(name)
        if port is not None:
            ports.setdefault(port[1], {})[name] = inode
        elif inode not in in_use and not _owner_in_use(name, in_use) and _unlink_unchanged(name, inode):
            removed.append(name)
    for port_name, files in sorted(ports.items()):
        removed += _remove_dead_port(port_name, files, in_use)
    return sorted(removed)


def _unlink_unchanged(name: str, inode: int) -> bool:
    """Remove SHM_DIR/name if it is still the file listed as `inode` (not one a new owner put there since)."""
    path = SHM_DIR / name
    try:
        if path.stat().st_ino != inode:
            return False
        path.unlink()
    except OSError:
        return False
    return True


#: A Fast DDS port's files: its segment, its listeners' lock files ("_el" exclusive, "_sl" shared) and its named
#: mutex (a POSIX semaphore, "sem." ... "_mutex"); group 1 is the segment's name.
_PORT_FILE = re.compile(r"(?:sem\.)?((?:fastdds|fastrtps)_port\d+)(?:_el|_sl|_mutex)?")
#: bytes of a glibc sem_t, the size of the file sem_open makes
_SEMAPHORE_SIZE = 32


def _remove_dead_port(port: str, listed: dict[str, int], in_use: set[int]) -> list[str]:
    """Remove a dead port's listed files, holding the port's mutex as Fast DDS's participants do.

    A participant that opens a port takes the port's mutex, tests whether the port is a dead one's (its lock file
    exists and nobody holds its lock), and if so replaces the segment and locks a new lock file; a writer opens the
    same way. Removing by name outside that mutex raced it: a clean-up that listed a dead port could remove the
    mutex or the lock file under a new owner that took the port after the scan, and the next opener then ran beside
    it (two creators of one segment; a listener left mapping a segment that writers no longer open). Here the mutex
    is tried without waiting (a port being opened is left for a later clean-up), the listeners' locks are tested
    while it is held (no opener can be between its zombie test and its lock then), and the mutex's own file is never
    removed: an opener may be waiting on it. It is a page, reused by the next participant on that port.

    Returns:
        The names removed.
    """
    files = {name: inode for name, inode in listed.items() if not name.endswith("_mutex")}
    if not files or any(inode in in_use for inode in files.values()):
        return []
    with contextlib.suppress(OSError):
        if (SHM_DIR / port).stat().st_ino in in_use:
            return []  # a live participant maps the segment
    with _port_mutex(port) as held:
        if not held or _lock_held(SHM_DIR / f"{port}_el") or _lock_held(SHM_DIR / f"{port}_sl"):
            return []
        return [name for name, inode in sorted(files.items()) if _unlink_unchanged(name, inode)]


@contextlib.contextmanager
def _port_mutex(port: str) -> Iterator[bool]:
    """Hold a Fast DDS port's named mutex if nobody holds it now; yields whether it is held.

    Fast DDS's named mutex is a POSIX semaphore whose file sem_open maps; mapping that file here and calling
    sem_trywait and sem_post on it is what sem_open's users do, and it lets a test put the file elsewhere."""
    path = SHM_DIR / f"sem.{port}_mutex"
    try:
        handle = os.open(path, os.O_RDWR | os.O_NOFOLLOW)
    except OSError:
        yield False  # none: a Fast DDS opener creates it at once and would not see ours
        return
    try:
        if os.fstat(handle).st_size < _SEMAPHORE_SIZE:
            yield False
            return
        mapping = mmap.mmap(handle, _SEMAPHORE_SIZE)
    finally:
        os.close(handle)
    semaphore = ctypes.c_char.from_buffer(mapping)
    try:
        address = ctypes.addressof(semaphore)
        if _libc().sem_trywait(ctypes.c_void_p(address)) != 0:
            yield False
            return
        try:
            yield True
        finally:
            _libc().sem_post(ctypes.c_void_p(address))
    finally:
        del semaphore
        mapping.close()


def _lock_held(path: Path) -> bool:
    """Whether someone holds a lock on `path` (a Fast DDS lock file); a file that cannot be tested counts as held."""
    try:
        handle = os.open(path, os.O_RDONLY | os.O_NOFOLLOW)
    except FileNotFoundError:
        return False
    except OSError:
        return True
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(handle)  # and with it our lock
    return False


@functools.cache
def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


#: s an empty Fast DDS port segment may stay empty. Its creator sizes it right after creating it (microseconds): one
#: empty for longer lost its creator in between (a process killed while it started) and will never be sized.
ABANDONED_PORT_AGE = 5.0
#: s between two looks for abandoned ports while a participant is being created (abandoned_ports_watched)
ABANDONED_PORT_PERIOD = 2.0
_PORT_SEGMENT = re.compile(r"(fastdds|fastrtps)_port\d+")


def free_abandoned_ports(min_age: float = ABANDONED_PORT_AGE) -> list[str]:
    """Remove the Fast DDS port segments that were created but never sized, and release whoever waits on them.

    Every participant on the machine opens the shared-memory port segments of its domain's discovery (and of the
    peers it talks to), each by name. A process killed between creating such a segment and sizing it leaves it
    empty, and from then on each participant that opens it waits, in its creation, for the size forever: a stress
    run of the suite saw every new Kilted process (test workers, simulators) hang in `rclpy.create_node` behind one
    empty `fastdds_port7000`, machine-wide. The segment is given a size of 1 byte first, which Boost's opener (the
    one Fast DDS uses) reads as a corrupted segment: it stops waiting, and Fast DDS creates the port anew. Then
    the name is removed, so the next participant creates a fresh segment.

    Args:
        min_age: seconds since its creation a segment must have stayed empty.

    Returns:
        The names removed.
    """
    if not SHM_DIR.is_dir():
        return []
    now = time.time()
    freed = []
    for path in SHM_DIR.iterdir():
        if not _PORT_SEGMENT.fullmatch(path.name):
            continue
        try:
            info = path.stat()
            if info.st_size != 0 or now - info.st_ctime < min_age:
                continue
            handle = os.open(path, os.O_WRONLY | os.O_NOFOLLOW)
        except OSError:
            continue
        try:
            opened = os.fstat(handle)
            if (opened.st_ino, opened.st_size) != (info.st_ino, 0):
                continue  # replaced or sized since the listing: someone's live port
            os.ftruncate(handle, 1)
            if path.stat().st_ino == info.st_ino:
                path.unlink()
                freed.append(path.name)
        except OSError:
            continue
        finally:
            os.close(handle)
    return freed


@contextlib.contextmanager
def abandoned_ports_watched(period: float = ABANDONED_PORT_PERIOD) -> Iterator[None]:
    """Free abandoned ports (free_abandoned_ports) now, and every `period` seconds while the block runs: wrap the
    creation of a process's first ROS node, where Fast DDS opens its ports. A port abandoned just before would
    otherwise hold that creation forever."""
    free_abandoned_ports()
    stop = threading.Event()

    def watch() -> None:
        while not stop.wait(period):
            with contextlib.suppress(OSError):
                free_abandoned_ports()

    watcher = threading.Thread(target=watch, name="tb4-abandoned-ports", daemon=True)
    watcher.start()
    try:
        yield
    finally:
        stop.set()


#: names the process that started a child; tb4's own programs (`end_with_parent`) end once it is gone
PARENT_ENV = "TB4_END_WITH_PARENT"
PARENT_WATCH_PERIOD = 0.5  # wall s between two looks at the parent
PARENT_GONE_GRACE = 15.0  # wall s for a clean shutdown after SIGINT before SIGKILL


def restore_stop_signals() -> None:
    """Let Ctrl-C and SIGTERM reach this process as they do from a terminal, whatever it inherited.

    Signal dispositions and the blocked-signal mask pass from parent to child. A process started from a background
    job of a script (`make test` runs its two stages so) inherits SIGINT ignored, which Python leaves so; one started
    by a Ray worker inherits SIGINT and SIGTERM blocked. Either way the clean shutdown its parent asks for
    (ManagedProcess.stop, tb4 run stopping its simulator) would be ignored until the SIGKILL that follows.
    """
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT, signal.SIGTERM})
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.default_int_handler)


def end_with_parent() -> None:
    """In a child a tb4 process started (`PARENT_ENV` names its parent): interrupt this process (SIGINT, as
    Ctrl-C: a clean ROS shutdown; SIGKILL if it is still here `PARENT_GONE_GRACE` s later) once that parent is
    gone. A child runs in a session of its own, so nothing else ends it: a `tb4 run` or a test that died hard left
    its simulator running at full speed, for good. The parent is watched by its id (a child whose parent has gone
    is given to another), in a daemon thread; the variable is taken out of the environment so that this process's
    own children do not watch a process that is not theirs."""
    value = os.environ.pop(PARENT_ENV, None)
    if value is None:
        return
    try:
        parent = int(value)
    except ValueError:
        print(f"tb4: ignoring {PARENT_ENV}={value!r}: not a process id", file=sys.stderr)
        return
    restore_stop_signals()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_WATCH_PERIOD)
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(PARENT_GONE_GRACE)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="tb4-parent-watch", daemon=True).start()


class ManagedProcess:
    """A child process in its own process group, always stopped by PID (SIGINT, then SIGTERM, then SIGKILL).
    One of tb4's own programs also ends by itself if this process dies first (`end_with_parent`)."""

    def __init__(
        self,
        args: Sequence[str],
        *,
        env: Mapping[str, str] | None = None,
        log_path: Path | None = None,
        cwd: str | Path | None = None,
        stdin: int | IO[bytes] | None = subprocess.DEVNULL,
    ) -> None:
        self.args = list(args)
        self.log_path = log_path
        self._log: IO[bytes] | None = open(log_path, "wb") if log_path else None  # noqa: SIM115
        self.popen = subprocess.Popen(
            self.args,
            env={**(os.environ if env is None else env), PARENT_ENV: str(os.getpid())},
            cwd=cwd,
            stdin=stdin,
            stdout=self._log if self._log else subprocess.DEVNULL,
            stderr=subprocess.STDOUT if self._log else subprocess.DEVNULL,
            start_new_session=True,
        )
        self.pid = self.popen.pid

    @classmethod
    def python(cls, module_args: Sequence[str], **kwargs) -> ManagedProcess:
        return cls([sys.executable, *module_args], **kwargs)

    def alive(self) -> bool:
        return self.popen.poll() is None

    def output(self) -> str:
        if self.log_path and self.log_path.exists():
            return self.log_path.read_text(errors="replace")
        return ""

    def wait_for_output(self, text: str, timeout: float) -> bool:
        """Wait until `text` appears in the log (True) or the timeout/exit (False)."""
        wait_until(lambda: text in self.output() or not self.alive(), timeout, period=0.05)
        return text in self.output()

    def interrupt(self) -> None:
        """Send SIGINT (a clean ROS shutdown) to the process group and return at once; `stop()` waits for it."""
        if self.alive():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.pid, signal.SIGINT)

    def abort_showing_stacks(self, timeout: float = 3.0) -> None:
        """End a Python process that did not finish in time so that its output says where it was: SIGABRT makes
        faulthandler, when the child runs with it on (PYTHONFAULTHANDLER=1), write every thread's stack there, even
        one stuck in C with the GIL held, before the process aborts. Waits at most `timeout` s; `stop()` ends
        whatever is left."""
        if self.alive():
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signal.SIGABRT)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.popen.wait(timeout)
        self.stop()

    def stop(self, timeout: float = 10.0) -> int | None:
        """Stop the process group: SIGINT (clean ROS shutdown), then SIGTERM, then SIGKILL. Returns the exit code.

        Once the process has exited and been reaped, its id is free and the system gives it to the next process
        it starts (ids wrap at 32,768 here): a signal sent to that id later would hit another process group, say
        another test's viewer. So a process already reaped gets no signal, only what its group left behind does.
        """
        for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
            if not self.alive():  # not reaped until this says so: the id is still ours here
                break
            try:
                os.killpg(self.pid, sig)
            except ProcessLookupError:
                break
            try:
                self.popen.wait(wait)
            except subprocess.TimeoutExpired:
                continue
        self._kill_leftovers()
        if self._log:
            self._log.close()
            self._log = None
        return self.popen.returncode

    def _kill_leftovers(self) -> None:
        """SIGKILL what is left of the group (a child the process started) once the process is gone. The group's
        id is the process's id, which is safe to signal only while no process has that id: one that has it now is
        a newer process, and a group it leads is its own (an id stays taken while a group of ours still uses it)."""
        if self.popen.returncode is None or _pid_alive(self.pid):
            return
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.pid, signal.SIGKILL)

    def __enter__(self) -> ManagedProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _pid_alive(pid: int) -> bool:
    """Whether some process has this id (another user's counts too)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _main(argv: Sequence[str]) -> int:
    """`python -m tb4.processes PID SNAPSHOT_FILE`: once PID has exited (30 s at most), remove the Fast DDS files
    that appeared since the snapshot and are unused. Lets a process clean up the segments it held itself."""
    pid, snapshot_file = int(argv[0]), Path(argv[1])
    wait_until(lambda: not _pid_alive(pid), 30.0, period=0.1)
    time.sleep(SHM_GRACE)  # the files it made last are young: left alone until they are SHM_GRACE old
    try:
        before = set(snapshot_file.read_text().split())
    finally:
        snapshot_file.unlink(missing_ok=True)
    remove_stale_shm(before)
    return 0


def clean_shm_after_exit(before: set[str]) -> None:
    """Arrange for our own stale Fast DDS segments to be removed once this process has exited."""
    import tempfile

    with tempfile.NamedTemporaryFile("w", prefix="tb4-shm-", suffix=".txt", delete=False) as handle:
        handle.write("\n".join(sorted(before)))
    subprocess.Popen(
        [sys.executable, "-m", "tb4.processes", str(os.getpid()), handle.name],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )


def flush_output() -> None:
    """Flush stdout and stderr, as the interpreter does on a normal exit: for a process about to end without one
    (os._exit, a signal with its default action). A stream that cannot be flushed (closed, a broken pipe) is left."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()


def exit_now(code: int, shm_before: set[str] | None = None) -> NoReturn:
    """End this process at once with `code`, its work done and its files closed: stdout and stderr are flushed,
    then os._exit skips the interpreter's finalization. In a process that had an rclpy context that takes about
    0.2 s (Fast DDS's participant teardown sleeps twice for 100 ms), and 0.1 to 0.2 s more with matplotlib
    loaded: a quarter of `tb4 run nav_to_pose`'s last second. The participant's shared-memory files stay behind;
    with `shm_before` (a snapshot from before it was created) a detached cleaner removes them once this process
    has gone (`clean_shm_after_exit`), else whoever started this process does (`remove_stale_shm`)."""
    flush_output()
    if shm_before is not None:
        with contextlib.suppress(OSError):
            clean_shm_after_exit(shm_before)
    os._exit(code)


def exit_within(seconds: float) -> None:
    """Make this process, its work done and only its teardown left, end within `seconds` wall seconds from now,
    whatever its threads wait on: once the time is up, faulthandler writes every Python thread's stack to stderr
    (under a "Timeout" line) and the process exits with status 1. faulthandler's own watchdog thread does it, which
    needs neither the GIL nor a live interpreter, so a teardown blocked in C (a middleware's threads waiting on
    each other while its entities are deleted) is ended too, and its log says where it was. Armed until the
    interpreter's last stage of finalization; a later call replaces the bound.

    Args:
        seconds: the bound, in wall seconds.
    """
    faulthandler.dump_traceback_later(seconds, exit=True, file=sys.stderr)


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
