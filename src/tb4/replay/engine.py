"""Re-running a recorded run from its input journal, with no DDS: `tb4 replay`.

The world is built from the journal's settings as the simulator built it (tb4.replay.core_world), and stepped by
the simulator's own loop (tb4.ros.loop.SimLoop, never started: no thread, no publishers, no ROS node), which is
handed each input on the tick the live run applied it. The replay keeps a journal of its own, so its digest and
checkpoints compare with the recording's one for one: equal digests mean every robot's pose after every tick is
the same to the last bit.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tb4.config import ConfigError
from tb4.replay.core_world import CoreSettings, build_core_world
from tb4.replay.journal import Checkpoint, Input, InputJournal, JournalFile, TaskNumbers, read_journal
from tb4.sim.world import load_world

__all__ = ["ReplayReport", "Divergence", "ReplayFeed", "replay", "find_journal", "ReplayError", "world_settings"]


class ReplayError(RuntimeError):
    """A run that cannot be replayed: no journal, a world that is gone, a journal that does not fit its world."""


@dataclass(frozen=True)
class Divergence:
    """Where the replay first left the recording: the first checkpoint whose poses differ."""

    tick: int
    time: float
    recorded: tuple[tuple[float, float, float], ...]
    replayed: tuple[tuple[float, float, float], ...]

    def describe(self) -> str:
        worst = (
            max(math.hypot(a[0] - b[0], a[1] - b[1]) for a, b in zip(self.recorded, self.replayed, strict=False))
            if self.recorded and self.replayed
            else math.nan
        )
        return f"first differs at tick {self.tick} (t={self.time:.2f} s): poses {worst:.3g} m apart"


@dataclass
class ReplayReport:
    """What a replay did and whether it reproduced the recording bit for bit."""

    journal: Path
    inputs: int
    ticks: int
    sim_time: float
    wall_time: float
    recorded_digest: str
    replayed_digest: str
    final_poses: tuple[tuple[float, float, float], ...]
    untracked: tuple[str, ...] = ()
    left_out: tuple[str, ...] = ()
    divergence: Divergence | None = None
    input_errors: list[str] = field(default_factory=list)
    trajectory: list[tuple[float, float, float, float]] = field(default_factory=list)  # (t, x, y, yaw) first robot

    @property
    def identical(self) -> bool:
        return self.recorded_digest == self.replayed_digest

    @property
    def reproducible(self) -> bool:
        """Whether the journal holds every change the run's motion depended on."""
        return not self.untracked

    def summary(self) -> str:
        rate = self.sim_time / self.wall_time if self.wall_time > 0 else math.inf
        head = (
            f"replayed {self.inputs} inputs over {self.ticks} ticks ({self.sim_time:.1f} sim s) "
            f"in {self.wall_time:.2f} s ({rate:.0f}x real time)"
        )
        if self.identical:
            return f"{head}: the trajectory is the recording's, bit for bit (digest {self.replayed_digest})"
        why = self.divergence.describe() if self.divergence is not None else "the digests differ"
        return f"{head}: the trajectory DIFFERS from the recording: {why}"

    def to_json(self) -> dict[str, Any]:
        return {
            "journal": str(self.journal),
            "inputs": self.inputs,
            "ticks": self.ticks,
            "sim_time": self.sim_time,
            "wall_time": round(self.wall_time, 3),
            "identical": self.identical,
            "reproducible": self.reproducible,
            "recorded_digest": self.recorded_digest,
            "replayed_digest": self.replayed_digest,
            "final_poses": [list(p) for p in self.final_poses],
            "untracked": list(self.untracked),
            "left_out": list(self.left_out),
            "divergence": None
            if self.divergence is None
            else {
                "tick": self.divergence.tick,
                "time": self.divergence.time,
                "recorded": [list(p) for p in self.divergence.recorded],
                "replayed": [list(p) for p in self.divergence.replayed],
            },
            "input_errors": self.input_errors,
        }


def find_journal(run: Path) -> Path:
    """The journal of a run folder, a run record (run.json) or the journal itself.

    Raises:
        ReplayError: nothing there, or a record without a journal (with why).
    """
    import json

    if run.is_dir():
        record = run / "run.json"
        if not record.is_file():
            raise ReplayError(f"{run}: not a run folder (no run.json in it)")
        run = record
    if not run.is_file():
        raise ReplayError(f"{run}: no such run folder, run record or journal")
    if run.name.endswith(".jsonl"):
        return run
    try:
        data = json.loads(run.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ReplayError(f"{run}: not a run record ({exc})") from None
    if not isinstance(data, dict) or "summary" not in data:
        raise ReplayError(f"{run}: not a run record (no summary)")
    replay_info = data.get("replay")
    if not isinstance(replay_info, dict) or not isinstance(replay_info.get("journal"), str):
        raise ReplayError(
            f"{run}: this run record has no input journal (recorded by an older tb4, or the simulator did not stop "
            "cleanly)"
        )
    journal = run.parent / Path(replay_info["journal"]).name
    if not journal.is_file():
        raise ReplayError(f"{run}: its journal {journal.name} is missing from {run.parent}")
    return journal


class ReplayFeed:
    """A journal's inputs fed to a SimLoop, each on its tick: the loop calls `before_tick` at the start of every
    tick (in its thread) and takes that tick in the fast-forward mode the run had. Used by `replay` here and by a
    simulator replaying a run for the viewer or a recording (`tb4 replay --view`)."""

    def __init__(self, journal: JournalFile, robots: int) -> None:
        self.path = journal.path
        self.last_tick = journal.end.ticks
        self._by_tick: dict[int, list[Input]] = defaultdict(list)
        for item in journal.inputs:
            if item.robot >= robots:
                raise ReplayError(f"{journal.path}: an input for robot {item.robot}, but the world has {robots}")
            if item.tick > self.last_tick:
                raise ReplayError(f"{journal.path}: an input after the journal's last tick ({item.tick})")
            self._by_tick[item.tick].append(item)
        self.fast_forward = False
        self.errors: list[str] = []
        # the tasks inputs started, numbered as the live run's journal numbered them
        self._tasks = TaskNumbers()

    def finished(self, tick: int) -> bool:
        """Whether tick `tick` lies past the run's end."""
        return tick > self.last_tick

    def before_tick(self, loop: Any, tick: int) -> bool:
        """Apply the inputs of `tick` (0: those applied before the first tick); returns the tick's fast-forward."""
        for item in self._by_tick.pop(tick, []):
            self._apply(loop, item)
        return self.fast_forward

    def _apply(self, loop: Any, item: Input) -> None:
        try:
            if item.target == "loop":
                self.fast_forward = bool(item.args[0])
            elif item.target == "task":
                task = self._tasks.task(item.index)
                if task is None:
                    raise ReplayError(f"{self.path}: tick {item.tick}: task {item.index} was never started")
                loop.cancel_now(item.robot, task)
            else:
                self._tasks.started(loop.apply(item.robot, item.target, item.method, item.args, item.kwargs))
        except ReplayError:
            raise
        except Exception as exc:  # as live: a refused input was answered with an error and the world went on
            self.errors.append(f"tick {item.tick}: {item.name}: {type(exc).__name__}: {exc}")


def world_settings(jf: JournalFile) -> tuple[Any, CoreSettings, float]:
    """The world, core settings and control period a journal's run started from.

    Raises:
        ReplayError: the world cannot be loaded, or the settings are malformed.
    """
    s = jf.settings
    world_file, world_name = s.get("world_file"), s.get("world")
    try:
        if isinstance(world_file, str) and Path(world_file).is_file():
            world = load_world(world_file)
        elif isinstance(world_name, str) and world_name:
            world = load_world(world_name)
        else:
            raise ReplayError(f"{jf.path}: the journal names no world")
    except (ConfigError, FileNotFoundError, ValueError) as exc:
        raise ReplayError(f"{jf.path}: its world cannot be loaded: {exc}") from None
    try:
        battery = s.get("battery")
        settings = CoreSettings(
            seed=int(s.get("seed", 0)),
            robots=int(s.get("robots", 0)),
            namespace=str(s.get("namespace", "")),
            battery=None if battery is None else float(battery),
            physics_dt=float(s.get("physics_dt", 0.01)),
            exact=bool(s.get("exact", False)),
            localization=str(s.get("localization", "amcl")),
        )
        control_period = float(s.get("control_period", 0.05))
    except (TypeError, ValueError) as exc:
        raise ReplayError(f"{jf.path}: malformed settings: {exc}") from None
    if not (math.isfinite(settings.physics_dt) and 0 < settings.physics_dt <= control_period <= 1.0):
        raise ReplayError(f"{jf.path}: physics_dt and control_period out of range")
    return world, settings, control_period


def replay(
    run: Path,
    on_sample: Callable[[float, list[tuple[float, float, float]]], None] | None = None,
    sample_period: float = 0.2,
) -> ReplayReport:
    """Re-run a recorded run from its journal and compare its trajectory with the recording's.

    Args:
        run: a run folder, its run.json, or the journal (run.inputs.jsonl).
        on_sample: called every `sample_period` sim seconds with the sim time and every robot's true pose.
        sample_period: see `on_sample` (also the period of the report's trajectory).

    Returns:
        The report: identical or not (and where it first differs), what the journal could not hold.

    Raises:
        ReplayError: no journal, a world that cannot be loaded, a journal that does not fit its world.
        JournalError: a malformed journal file.
    """
    from tb4.ros.loop import SimLoop  # the simulator's own loop, never started: no thread and no ROS node

    jf = read_journal(find_journal(run))
    world, settings, control_period = world_settings(jf)
    try:
        core = build_core_world(world, settings)
    except ValueError as exc:
        raise ReplayError(f"{jf.path}: {exc}") from None
    sims, navs = core.sims, core.navs
    loop = SimLoop(
        sims[0], navs[0], rate=math.inf, control_period=control_period, world=core.fleet or sims[0], navs=navs
    )
    journal = InputJournal(dict(jf.settings))
    loop.journal = journal
    feed = ReplayFeed(jf, len(sims))
    report = ReplayReport(
        jf.path, len(jf.inputs), 0, 0.0, 0.0, jf.end.digest, "", (), jf.end.untracked, jf.end.left_out
    )
    next_sample = 0.0
    started = time.perf_counter()
    feed.before_tick(loop, 0)
    loop.feed = feed
    for _ in range(jf.end.ticks):
        loop.tick()
        now = sims[0].time
        if now + 1e-9 >= next_sample:
            next_sample = now + sample_period
            poses = [(s.x, s.y, s.yaw) for s in sims]
            report.trajectory.append((now, *poses[0]))
            if on_sample is not None:
                on_sample(now, poses)
    report.wall_time = time.perf_counter() - started
    report.input_errors = feed.errors
    end = journal.end()
    report.ticks, report.sim_time, report.replayed_digest, report.final_poses = (
        end.ticks,
        end.time,
        end.digest,
        end.poses,
    )
    report.divergence = _first_divergence(jf.checkpoints, journal.checkpoints, jf.end, end)
    return report


def _first_divergence(
    recorded: tuple[Checkpoint, ...], replayed: list[Checkpoint], recorded_end: Any, replayed_end: Any
) -> Divergence | None:
    if recorded_end.digest == replayed_end.digest:
        return None
    mine = {c.tick: c for c in replayed}
    for c in recorded:
        other = mine.get(c.tick)
        if other is None or other.poses != c.poses:
            return Divergence(c.tick, c.time, c.poses, other.poses if other is not None else ())
    return Divergence(recorded_end.ticks, recorded_end.time, recorded_end.poses, replayed_end.poses)
