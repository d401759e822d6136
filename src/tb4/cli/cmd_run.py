"""`tb4 run NAME`: run a tutorial in the built-in simulator (or, with --attach, against a running one)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tb4.cli._arguments import number
from tb4.cli.cmd_sim import RATE_MAX_HELP, add_sensing_arguments
from tb4.tutorials import TUTORIALS, get_tutorial

__all__ = ["register"]


def _cmd_run(args: argparse.Namespace, extra: list[str]) -> int:
    if args.list or not args.name:
        width = max(len(n) for n in TUTORIALS)
        for tutorial in TUTORIALS.values():
            print(f"{tutorial.name:{width}s}  [{tutorial.world}]  {tutorial.summary}")
        return 0 if args.list else 2
    try:
        tutorial = get_tutorial(args.name)
    except KeyError as exc:
        print(f"tb4 run: {exc.args[0]}", file=sys.stderr)
        return 2
    from tb4.runner.session import RunOptions, run_tutorial  # it checks the ROS side (require_ros) itself

    if args.json:
        mode = "json"
    elif args.quiet:
        mode = "quiet"
    elif sys.stdout.isatty() and not tutorial.interactive:
        mode = "live"
    else:
        mode = "plain"
    tutorial_args = list(extra)
    if args.laps is not None:
        tutorial_args += ["--laps", str(args.laps)]
    if args.sim_hours is not None:
        tutorial_args += ["--sim-hours", str(args.sim_hours)]
    options = RunOptions(
        world=args.world,
        rate=args.rate,
        seed=args.seed,
        battery=args.battery,
        namespace=args.namespace,
        output_dir=Path(args.output_dir),
        mode=mode,
        record=Path(args.record) if args.record else None,
        view=args.view,
        attach=args.attach,
        tutorial_args=tutorial_args,
        exact=args.exact,
        localization=args.localization,
        shm_before=getattr(args, "shm_before", None),  # the one tb4's main took for exit_now, if it did
    )
    outcome = run_tutorial(tutorial, options)
    if mode == "json":
        import json

        print(
            json.dumps(
                {
                    "event": "end",
                    "exit_code": outcome.exit_code,
                    "reason": outcome.reason,
                    "picture": str(outcome.picture) if outcome.picture else None,
                    "record": str(outcome.record) if outcome.record else None,
                    "mcap": str(outcome.mcap) if outcome.mcap else None,
                }
            ),
            flush=True,
        )
    else:
        if outcome.picture is not None and mode != "quiet":
            print(f"picture of the run: {outcome.picture}")
        if outcome.mcap is not None and mode != "quiet":
            print(f"recording: {outcome.mcap}")
        verdict = "succeeded" if outcome.exit_code == 0 else f"failed: {outcome.reason}"
        print(f"tb4 run {tutorial.name} {verdict}")
    return outcome.exit_code


def register(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser(
        "run",
        help="run a tutorial in the built-in simulator",
        description="Start the simulator with the tutorial's world, run the tutorial against it over ROS 2, stop "
        "the simulator, and save a picture of the run. Arguments after the known options go to the tutorial.",
    )
    run.add_argument("name", nargs="?", help="tutorial name (see --list)")
    run.add_argument("--list", action="store_true", help="list the tutorials")
    run.add_argument("--world", default=None, help="world name or file (default: the tutorial's own)")
    run.add_argument(
        "--rate",
        default="max",
        help=f"simulation speed: 1 (real time), N (N times), {RATE_MAX_HELP} (default)",
    )
    run.add_argument("--seed", type=int, default=0)
    run.add_argument("--battery", type=number("battery", 0.0, 1.0), default=None, help="start battery level, 0..1")
    run.add_argument("--namespace", default="")
    add_sensing_arguments(run)
    run.add_argument("--output-dir", default="runs", help="where run folders go (default: ./runs)")
    run.add_argument("--record", metavar="FILE.mcap", help="record the run's ROS topics to an MCAP file")
    run.add_argument("--view", action="store_true", help="serve the live web viewer during the run")
    run.add_argument("--attach", action="store_true", help="use a simulator or robot that is already running")
    run.add_argument("--quiet", action="store_true", help="only the final line")
    run.add_argument("--json", action="store_true", help="one JSON event per line on stdout")
    run.add_argument("--laps", type=int, default=None, help="patrol_loop: stop after N laps")
    run.add_argument("--sim-hours", type=float, default=None, help="patrol_loop: stop after H hours of sim time")
    run.set_defaults(func=_cmd_run, takes_extra=True, exit_fast=True)  # see tb4.processes.exit_now
