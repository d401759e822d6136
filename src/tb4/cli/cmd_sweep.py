"""`tb4 sweep MISSION --seeds 0:1000 [--world a,b] [--battery 0.3,0.9] ...`: a mission's success rate over a matrix
of trials, in parallel on this machine or on a Ray cluster (`--ray [ADDRESS]`)."""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path
from typing import Any

from tb4.cli._arguments import number

__all__ = ["register"]


def _matrix(args: argparse.Namespace) -> list[Any]:
    from tb4.sweep.matrix import build_matrix, parse_list, parse_seeds

    batteries: list[float | None] = [None]
    if args.battery:
        batteries = []
        for text in parse_list(args.battery, "--battery"):
            try:
                batteries.append(float(text))
            except ValueError:
                raise ValueError(f"--battery: {text!r} is not a number between 0 and 1") from None
    localizations = parse_list(args.localization, "--localization")
    for name in localizations:
        if name not in ("amcl", "truth", "odometry"):
            raise ValueError(f"--localization: {name!r} is not amcl, truth or odometry")
    worlds = parse_list(args.world, "--world") if args.world else []
    return build_matrix(parse_seeds(args.seeds), worlds, batteries, (args.exact,), localizations)


def _check_worlds(worlds: list[str]) -> None:
    from tb4.sim.world import load_world

    for world in worlds:
        load_world(world)  # a ConfigError with "did you mean" before any trial starts


def _cmd_sweep(args: argparse.Namespace, extra: list[str]) -> int:
    from tb4.config import ConfigError
    from tb4.runner.missions import MissionError, resolve_mission
    from tb4.sweep import Sweep, SweepError, SweepSpec

    try:
        mission = resolve_mission(args.mission, module=args.module, world=None, robots=args.robots)
        if not args.world:
            args.world = mission.world
        trials = _matrix(args)
        _check_worlds(sorted({trial.world for trial in trials}))
    except (MissionError, ValueError, ConfigError) as exc:
        print(f"tb4 sweep: {exc}", file=sys.stderr)
        return 2
    target = mission.target if mission.kind != "tutorial" else mission.name
    spec = SweepSpec(
        target=target,
        trials=trials,
        arguments=extra[1:] if extra[:1] == ["--"] else list(extra),
        module=args.module,
        rate=args.rate,
        robots=args.robots,
        time_limit=args.time_limit,
        record=args.record,
        fail_on_bump=args.fail_on_bump,
        keep_runs=args.keep_runs,
        reuse=not args.new_simulators,
    )
    folder = Path(args.output or f"sweeps/{mission.name}-{time.strftime('%Y%m%d-%H%M%S')}")
    try:
        sweep = Sweep(spec, folder, workers=args.workers, resume=args.resume, ray_address=args.ray)
    except SweepError as exc:
        print(f"tb4 sweep: {exc}", file=sys.stderr)
        return 2
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: sweep.cancel())
    done_before = len(spec.trials) - len(sweep.pending)
    where = f"Ray cluster {args.ray or '(local)'}" if args.ray is not None else f"{sweep.workers} workers"
    if not args.json:
        resumed = f", {done_before} already done" if done_before else ""
        print(f"tb4 sweep {mission.name}: {len(spec.trials)} trials on {where}{resumed}; results in {folder}")
    progress = _Progress(len(spec.trials), done_before, args.json)
    try:
        table = sweep.run(on_row=progress.row)
    except Exception as exc:  # RayUnavailable and friends: said plainly, the rows kept so far stay on disk
        progress.close()
        print(f"tb4 sweep: {exc}", file=sys.stderr)
        return 2
    progress.close()
    from tb4.sweep.results import format_summary

    summary = table.summary()
    if args.junit:
        table.write_junit(Path(args.junit), f"tb4 sweep {mission.name}")
    if args.json:
        import json

        print(json.dumps({"event": "end", "folder": str(folder), "canceled": sweep.canceled, **summary}), flush=True)
    else:
        print(format_summary(summary))
        print(f"results: {folder / 'results.csv'}, {folder / 'summary.txt'}")
        if sweep.canceled:
            print(f"tb4 sweep: interrupted; {len(table)} rows kept: tb4 sweep ... --output {folder} --resume goes on")
    if sweep.canceled:
        return 130
    return 0 if all(row.outcome == "succeeded" for row in table) else 1


class _Progress:
    """A progress bar with an ETA on a terminal; a line every few trials otherwise; JSON rows with --json."""

    def __init__(self, total: int, done: int, as_json: bool) -> None:
        self.total, self.done, self.failed = total, done, 0
        self.as_json = as_json
        self.started = time.monotonic()
        self.fresh = 0
        self._bar: Any = None
        if not as_json and sys.stdout.isatty():
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self._bar = Progress(
                TextColumn("[bold]sweep"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[failed]}"),
                TimeRemainingColumn(),
            )
            self._task = self._bar.add_task("sweep", total=total, completed=done, failed="")
            self._bar.start()

    def row(self, row: Any) -> None:
        self.done += 1
        self.fresh += 1
        self.failed += row.outcome != "succeeded"
        if self.as_json:
            import dataclasses
            import json

            print(json.dumps({"event": "row", **dataclasses.asdict(row)}), flush=True)
        elif self._bar is not None:
            self._bar.update(self._task, completed=self.done, failed=f"{self.failed} failed" if self.failed else "")
        elif self.fresh % max(1, self.total // 20) == 0 or self.done == self.total:
            elapsed = time.monotonic() - self.started
            eta = elapsed / self.fresh * (self.total - self.done)
            print(f"[tb4 sweep] {self.done}/{self.total} done, {self.failed} failed, ETA {eta:.0f} s", flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()


def register(sub: argparse._SubParsersAction) -> None:
    from tb4.cli.cmd_sim import RATE_MAX_HELP

    sweep = sub.add_parser(
        "sweep",
        help="a mission's success rate over many seeds (and worlds, batteries), in parallel or on a Ray cluster",
        description="Run a tutorial or your own mission (a script, or -m package.module) once per trial of the "
        "matrix --seeds x --world x --battery x --localization, each in a simulator of its own, in parallel on "
        "this machine (or as Ray tasks with --ray). Writes results.jsonl (each row as it ends), results.csv, "
        "summary.txt/.json (success rate per cell with its Wilson 95 %% interval, sim time p50/p95, failures by "
        "reason) and, with --junit, JUnit XML. Failures keep their run folder (picture, record) and their row says "
        "how to run them again. Ctrl-C keeps the finished rows; --resume goes on. Arguments after -- go to the "
        "mission. Exit code: 0 all succeeded, 1 some did not, 2 bad input, 130 interrupted.",
    )
    sweep.add_argument("mission", help="a tutorial name, a script path, or with -m a module")
    sweep.add_argument("-m", "--module", action="store_true", help="MISSION is a module, run as python -m")
    sweep.add_argument("--seeds", required=True, help="seeds: N, START:STOP (STOP excluded) or a comma list")
    sweep.add_argument("--world", default=None, help="world(s), comma-separated (default: the mission's)")
    sweep.add_argument("--battery", default=None, help="start battery level(s) 0..1, comma-separated")
    sweep.add_argument("--localization", default="amcl", help="amcl, truth or odometry, comma-separated")
    sweep.add_argument("--exact", action="store_true", help="no odometry drift and no lidar noise")
    sweep.add_argument("--rate", default="max", help=f"simulation speed: {RATE_MAX_HELP} (default), or N")
    sweep.add_argument("--robots", type=number("robots", 1, 64, integer=True), default=0, metavar="N")
    sweep.add_argument(
        "--workers",
        type=number("workers", 1, 256, integer=True),
        default=None,
        help="trials at once (default: cores, plus two when trials reuse simulators)",
    )
    sweep.add_argument(
        "--time-limit",
        type=number("time limit", 1.0, 86400.0),
        default=600.0,
        metavar="SECONDS",
        help="wall seconds a trial may run; then it is ended and counted as timed out (default 600)",
    )
    sweep.add_argument(
        "--new-simulators",
        action="store_true",
        help="run every trial as a `tb4 run` of its own (a new simulator and mission process each), instead of "
        "resetting one simulator per worker between trials",
    )
    sweep.add_argument("--record", action="store_true", help="record each trial to MCAP (kept for failures)")
    sweep.add_argument("--fail-on-bump", action="store_true", help="a bump fails the trial")
    sweep.add_argument("--keep-runs", action="store_true", help="keep the run folders of successes too")
    sweep.add_argument("--output", default=None, metavar="DIR", help="results folder (default: sweeps/NAME-DATE)")
    sweep.add_argument("--resume", action="store_true", help="continue the sweep in --output: only missing trials")
    sweep.add_argument("--junit", default=None, metavar="FILE.xml", help="also write JUnit XML (one case per trial)")
    sweep.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="run the trials as Ray tasks: on the cluster at ADDRESS (HOST:PORT, auto), or a local Ray without one",
    )
    sweep.add_argument("--json", action="store_true", help="one JSON line per trial, then the summary")
    sweep.set_defaults(func=_cmd_sweep, takes_extra=True)
