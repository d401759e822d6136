"""The input journal: every input the simulator's world received, at the tick it took effect, to replay a run.

A simulator's run is a function of its settings (world, seed, robots, battery, noise, localization) and of its
inputs: goals, cancels, velocity commands, initial poses, button presses, each applied by the loop between two
ticks. Over DDS the tick an input lands on depends on the machine's timing, so two live runs of one seed differ;
the journal writes down which input landed on which tick, and `tb4 replay` re-runs the world from it with no DDS.

An input is a call of a named method of the core (`nav.start_navigate_to_pose`, `sim.set_velocity_command`,
`task.cancel`, ...) with plain, JSON-safe arguments: the allow-list INPUTS names every method an input may call,
so a replay never runs anything else, whatever a journal file holds. A change of the world that is not such an
input (a map switch) is noted as `untracked`: replay then says the run cannot be reproduced and why, instead of
silently differing. A change that cannot alter any robot's motion (a light ring, a sound) is noted as `left_out`.

The file is JSON lines: a header with the settings, the inputs in order, a checkpoint of every robot's pose now
and then (to say where a replay first differs), and an end line with the tick count and a digest of every robot's
pose (x, y, yaw as float64) after every tick: a replay reproduces a run bit for bit when its digest matches.
"""

from __future__ import annotations

import hashlib
import json
import math
import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "INPUTS",
    "JOURNAL_VERSION",
    "CHECKPOINT_TICKS",
    "MAX_TICKS",
    "Input",
    "Checkpoint",
    "JournalEnd",
    "InputJournal",
    "JournalError",
    "JournalFile",
    "TrajectoryDigest",
    "TaskNumbers",
    "encode",
    "decode",
    "read_journal",
    "journal_path_for",
]

JOURNAL_VERSION = 1

#: ticks between two checkpoints (one sim second at the default control period of 50 ms)
CHECKPOINT_TICKS = 20

#: the most ticks a journal may claim (about 11.6 sim days at 50 ms a tick, idle spans on the dock counting one
#: tick each): a replay steps every one, so a file claiming more would keep it busy for hours
MAX_TICKS = 20_000_000

#: every method an input may call, by target. `loop.fast_forward` is the loop's own switch to taking a docked
#: robot's idle periods together (on at --rate max once the start-up hold ends); `task.*` act on a task an earlier
#: input started, named by its number in start order.
INPUTS: dict[str, frozenset[str]] = {
    "loop": frozenset({"fast_forward"}),
    "sim": frozenset(
        {
            "set_velocity_command",
            "start_drive_goal",
            "start_dock",
            "start_undock",
            "stop_motion",
            "reset_odometry",
            "kidnap",
        }
    ),
    "base": frozenset({"press", "set_safety_override", "set_estop", "power_off"}),
    "nav": frozenset(
        {
            "set_initial_pose",
            "global_localization",
            "request_nomotion_update",
            "start_navigate_to_pose",
            "start_navigate_through_poses",
            "start_follow_waypoints",
            "start_follow_path",
            "start_spin",
            "start_backup",
            "start_drive_on_heading",
            "start_wait",
            "start_assisted_teleop",
            "teleop_velocity",
            "preempt_teleop",
            "pause",
            "resume",
            "clear_global",
            "clear_local",
            "clear_global_around",
            "clear_global_except",
            "clear_local_around",
            "clear_local_except",
        }
    ),
    "docking": frozenset({"start_dock_robot", "start_undock_robot"}),
    "task": frozenset({"cancel"}),
}


class JournalError(ValueError):
    """A journal file that cannot be read: the file, the line and what is wrong."""


def encode(value: Any) -> Any:
    """A core argument as JSON-safe data that `decode` turns back into an equal value, bit for bit.

    Floats go as JSON numbers (Python writes the shortest text that reads back to the same double; NaN and
    infinities as JSON's common extensions); tuples and NumPy arrays are tagged so they come back as such.

    Args:
        value: None, a bool, int, float or str, or a list, tuple or dict (str keys) of them, or a NumPy array.

    Returns:
        The encoded value.

    Raises:
        TypeError: for anything else (an input must be plain data to be replayable).
    """
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value
    if isinstance(value, np.generic):
        return encode(value.item())
    if isinstance(value, np.ndarray):
        return {"__array__": str(value.dtype), "shape": list(value.shape), "data": value.ravel().tolist()}
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        if any(k.startswith("__") for k in value):
            raise TypeError("a dict input's keys must not start with '__'")
        return {k: encode(v) for k, v in value.items()}
    raise TypeError(f"{type(value).__name__} is not a replayable input value")


_ARRAY_DTYPES = frozenset({"float64", "float32", "int64", "int32", "int8", "uint8", "bool"})


def decode(data: Any) -> Any:
    """The value `encode` wrote.

    Args:
        data: what json.loads read.

    Returns:
        The value, with its tuples and arrays restored.

    Raises:
        JournalError: a malformed tagged value.
    """
    if isinstance(data, list):
        return [decode(v) for v in data]
    if isinstance(data, dict):
        if "__tuple__" in data:
            items = data["__tuple__"]
            if not isinstance(items, list):
                raise JournalError("a tuple's items must be a list")
            return tuple(decode(v) for v in items)
        if "__array__" in data:
            dtype, shape, values = data.get("__array__"), data.get("shape"), data.get("data")
            if dtype not in _ARRAY_DTYPES or not isinstance(shape, list) or not isinstance(values, list):
                raise JournalError(f"a malformed array (dtype {dtype!r})")
            if not all(isinstance(n, int) and n >= 0 for n in shape) or math.prod(shape) != len(values):
                raise JournalError(f"an array's shape {shape} does not hold its {len(values)} values")
            return np.asarray(values, dtype=dtype).reshape(shape)
        return {k: decode(v) for k, v in data.items()}
    return data


@dataclass(frozen=True)
class Input:
    """One input: `target.method(*args, **kwargs)` on robot `robot`, applied before the physics of tick `tick`.

    `index` is the task number for target `task`."""

    tick: int
    robot: int
    target: str
    method: str
    args: tuple[Any, ...] = ()
    kwargs: dict[str, Any] = field(default_factory=dict)
    index: int = -1

    @property
    def name(self) -> str:
        return f"{self.target}.{self.method}" if self.index < 0 else f"task {self.index}.{self.method}"

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"tick": self.tick, "robot": self.robot, "call": f"{self.target}.{self.method}"}
        if self.index >= 0:
            out["task"] = self.index
        if self.args:
            out["args"] = [encode(a) for a in self.args]
        if self.kwargs:
            out["kwargs"] = {k: encode(v) for k, v in self.kwargs.items()}
        return out


@dataclass(frozen=True)
class Checkpoint:
    """Every robot's true pose (x, y, yaw) after tick `tick`, at sim time `time`."""

    tick: int
    time: float
    poses: tuple[tuple[float, float, float], ...]


@dataclass(frozen=True)
class JournalEnd:
    """How the run ended: its tick count, sim time, trajectory digest, final poses and what replay cannot redo."""

    ticks: int
    time: float
    digest: str
    poses: tuple[tuple[float, float, float], ...]
    untracked: tuple[str, ...] = ()
    left_out: tuple[str, ...] = ()


class TaskNumbers:
    """The tasks inputs started, numbered in start order: a live run and its replay number theirs alike, so an
    input acting on a task (a cancel) names it by its number."""

    def __init__(self) -> None:
        self._numbers: dict[int, int] = {}  # id(task) -> number
        self._tasks: list[Any] = []  # keeps numbered tasks alive, so no id is reused

    def started(self, result: Any) -> None:
        """Number what an input returned, if it is a task (it can be canceled) not numbered yet."""
        if id(result) not in self._numbers and hasattr(result, "cancel"):
            self._numbers[id(result)] = len(self._tasks)
            self._tasks.append(result)

    def number(self, task: Any) -> int | None:
        return self._numbers.get(id(task))

    def task(self, number: int) -> Any:
        """The task numbered `number` (None: no such task was started)."""
        return self._tasks[number] if 0 <= number < len(self._tasks) else None


class TrajectoryDigest:
    """A running hash of every robot's pose after every tick: equal digests, equal trajectories to the bit."""

    def __init__(self) -> None:
        self._hash = hashlib.blake2b(digest_size=16)

    def add(self, tick: int, poses: Iterable[tuple[float, float, float]]) -> None:
        h = self._hash
        h.update(struct.pack("<q", tick))
        for x, y, yaw in poses:
            h.update(struct.pack("<3d", x, y, yaw))

    def hexdigest(self) -> str:
        return self._hash.hexdigest()


@dataclass
class InputJournal:
    """What a live run writes: the settings, the inputs as the loop applies them, checkpoints and the end.

    Everything is appended from the loop thread; `write` runs once the loop has stopped."""

    settings: dict[str, Any]
    inputs: list[Input] = field(default_factory=list)
    checkpoints: list[Checkpoint] = field(default_factory=list)
    untracked: list[str] = field(default_factory=list)
    left_out: list[str] = field(default_factory=list)
    digest: TrajectoryDigest = field(default_factory=TrajectoryDigest)
    ticks: int = 0
    time: float = 0.0
    poses: tuple[tuple[float, float, float], ...] = ()
    tasks: TaskNumbers = field(default_factory=TaskNumbers)

    def add(self, tick: int, robot: int, target: str, method: str, args: Sequence[Any], kwargs: dict[str, Any]) -> None:
        """Note an input about to be applied (the loop thread)."""
        if method not in INPUTS.get(target, ()):
            raise ValueError(f"{target}.{method} is not a replayable input (tb4.replay.journal.INPUTS)")
        self.inputs.append(Input(tick, robot, target, method, tuple(args), dict(kwargs)))

    def add_task_call(self, tick: int, robot: int, task: Any, method: str) -> bool:
        """Note `task.method()` on a task an input started; False (nothing noted) for a task no input started."""
        number = self.tasks.number(task)
        if number is None:
            return False
        self.inputs.append(Input(tick, robot, "task", method, index=number))
        return True

    def untrack(self, reason: str, moves: bool = True) -> None:
        """Note a change no input expresses: with `moves`, one replay cannot redo (the run is not reproducible
        from the journal); without, one that cannot change any robot's motion, which replay leaves out."""
        kept = self.untracked if moves else self.left_out
        if reason not in kept:
            kept.append(reason)

    def after_tick(self, tick: int, time: float, poses: tuple[tuple[float, float, float], ...]) -> None:
        self.digest.add(tick, poses)
        self.ticks, self.time, self.poses = tick, time, poses
        if tick % CHECKPOINT_TICKS == 0:
            self.checkpoints.append(Checkpoint(tick, time, poses))

    def end(self) -> JournalEnd:
        return JournalEnd(
            self.ticks, self.time, self.digest.hexdigest(), self.poses, tuple(self.untracked), tuple(self.left_out)
        )

    def write(self, path: Path) -> Path:
        """Write the journal as JSON lines (header, inputs and checkpoints in tick order, end)."""
        end = self.end()
        lines = [json.dumps({"tb4_journal": JOURNAL_VERSION, "settings": self.settings})]
        records: list[tuple[int, int, dict[str, Any]]] = [(i.tick, 0, i.to_json()) for i in self.inputs]
        records += [
            (c.tick, 1, {"checkpoint": c.tick, "time": c.time, "poses": [list(p) for p in c.poses]})
            for c in self.checkpoints
        ]
        records.sort(key=lambda r: (r[0], r[1]))  # stable: inputs keep their order within a tick
        lines += [json.dumps(r[2]) for r in records]
        lines.append(
            json.dumps(
                {
                    "end": {
                        "ticks": end.ticks,
                        "time": end.time,
                        "digest": end.digest,
                        "poses": [list(p) for p in end.poses],
                        "untracked": list(end.untracked),
                        "left_out": list(end.left_out),
                    }
                }
            )
        )
        path.write_text("\n".join(lines) + "\n")
        return path


@dataclass(frozen=True)
class JournalFile:
    """A journal as read back: settings, inputs, checkpoints, end."""

    path: Path
    settings: dict[str, Any]
    inputs: tuple[Input, ...]
    checkpoints: tuple[Checkpoint, ...]
    end: JournalEnd


def _poses(data: Any, where: str) -> tuple[tuple[float, float, float], ...]:
    if not isinstance(data, list) or not all(
        isinstance(p, list) and len(p) == 3 and all(isinstance(v, (int, float)) for v in p) for p in data
    ):
        raise JournalError(f"{where}: poses must be a list of [x, y, yaw]")
    return tuple((float(p[0]), float(p[1]), float(p[2])) for p in data)


def _input(data: dict[str, Any], where: str) -> Input:
    call, tick, robot = data.get("call"), data.get("tick"), data.get("robot", 0)
    if not isinstance(call, str) or "." not in call:
        raise JournalError(f"{where}: 'call' must name a target and a method, e.g. 'nav.start_spin'")
    target, method = call.split(".", 1)
    if method not in INPUTS.get(target, ()):
        raise JournalError(f"{where}: {call!r} is not a replayable input")
    if not isinstance(tick, int) or tick < 0 or not isinstance(robot, int) or robot < 0:
        raise JournalError(f"{where}: 'tick' and 'robot' must be whole numbers >= 0")
    args, kwargs, index = data.get("args", []), data.get("kwargs", {}), data.get("task", -1)
    if not isinstance(args, list) or not isinstance(kwargs, dict) or not isinstance(index, int):
        raise JournalError(f"{where}: 'args' must be a list, 'kwargs' an object, 'task' a number")
    if (target == "task") != (index >= 0):
        raise JournalError(f"{where}: a task call needs a task number, and only a task call has one")
    try:
        return Input(tick, robot, target, method, tuple(decode(a) for a in args), decode(kwargs), index)
    except (JournalError, ValueError, TypeError) as exc:
        raise JournalError(f"{where}: {exc}") from None


def read_journal(path: Path) -> JournalFile:
    """Read a journal file written by `InputJournal.write`.

    Args:
        path: the journal (JSON lines).

    Returns:
        The journal.

    Raises:
        JournalError: the file is missing, is not a journal, or a line is malformed (with its number).
    """
    try:
        text = path.read_text()
    except OSError as exc:
        raise JournalError(f"{path}: cannot read the journal: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise JournalError(f"{path}: not a journal (not text)") from None
    settings: dict[str, Any] | None = None
    inputs: list[Input] = []
    checkpoints: list[Checkpoint] = []
    end: JournalEnd | None = None
    for number, line in enumerate(text.splitlines(), 1):
        where = f"{path}:{number}"
        if not line.strip():
            continue
        try:
            data = json.loads(line)
        except json.JSONDecodeError as exc:
            raise JournalError(f"{where}: not JSON ({exc.msg})") from None
        if not isinstance(data, dict):
            raise JournalError(f"{where}: each line must be a JSON object")
        if settings is None:
            if data.get("tb4_journal") != JOURNAL_VERSION or not isinstance(data.get("settings"), dict):
                raise JournalError(f"{where}: not a tb4 input journal (version {JOURNAL_VERSION} header expected)")
            settings = data["settings"]
        elif end is not None:
            raise JournalError(f"{where}: a line after the journal's end")
        elif "checkpoint" in data:
            tick, time = data.get("checkpoint"), data.get("time")
            if not isinstance(tick, int) or not isinstance(time, (int, float)):
                raise JournalError(f"{where}: a checkpoint needs its tick and time")
            checkpoints.append(Checkpoint(tick, float(time), _poses(data.get("poses"), where)))
        elif "end" in data:
            e = data["end"]
            if not isinstance(e, dict) or not isinstance(e.get("ticks"), int) or not isinstance(e.get("digest"), str):
                raise JournalError(f"{where}: the end line needs 'ticks' and 'digest'")
            if not 0 <= e["ticks"] <= MAX_TICKS:
                raise JournalError(f"{where}: {e['ticks']} ticks: a journal holds 0 to {MAX_TICKS}")
            reasons = {key: e.get(key, []) for key in ("untracked", "left_out")}
            for key, value in reasons.items():
                if not isinstance(value, list) or not all(isinstance(u, str) for u in value):
                    raise JournalError(f"{where}: {key!r} must be a list of reasons")
            end = JournalEnd(
                e["ticks"],
                float(e.get("time", 0.0)),
                e["digest"],
                _poses(e.get("poses", []), where),
                tuple(reasons["untracked"]),
                tuple(reasons["left_out"]),
            )
        else:
            inputs.append(_input(data, where))
    if settings is None:
        raise JournalError(f"{path}: empty: not a tb4 input journal")
    if end is None:
        raise JournalError(f"{path}: the journal has no end line (the simulator did not stop cleanly)")
    return JournalFile(path, settings, tuple(inputs), tuple(checkpoints), end)


def journal_path_for(record_path: Path) -> Path:
    """Where a run record's journal goes: beside it, `run.json` -> `run.inputs.jsonl`."""
    return record_path.with_name(record_path.stem + ".inputs.jsonl")
