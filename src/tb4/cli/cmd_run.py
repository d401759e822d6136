"""`tb4 run NAME|SCRIPT|-m MODULE`: run a tutorial or a mission of your own in the built-in simulator (or, with
--attach, against a running one)."""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path

from tb4.cli._arguments import number
from tb4.cli.cmd_sim import RATE_MAX_HELP, add_sensing_arguments
from tb4.foxglove import add_foxglove_arguments, foxglove_options
from tb4.tutorials import TUTORIALS

__all__ = ["register"]


def _cmd_run(args: argparse.Namespace, extra: list[str]) -> int:
    if args.list or not args.name:
        width = max(len(n) for n in TUTORIALS)
        for tutorial in TUTORIALS.values():
            print(f"{tutorial.name:{width}s}  [{tutorial.world}]  {tutorial.summary}")
        return 0 if args.list else 2
    from tb4.runner.missions import MissionError, resolve_mission

    try:
        mission = resolve_mission(
            args.name, module=args.module, world=args.world, robots=args.robots, interactive=args.interactive
        )
    except MissionError as exc:
        print(f"tb4 run: {exc}", file=sys.stderr)
        return 2
    from tb4.runner.session import RunOptions, run_mission  # it checks the ROS side (require_ros) itself

    try:
        foxglove = foxglove_options(args)
        if foxglove is not None and args.view and foxglove.port == RunOptions.view_port:
            raise ValueError(f"--view and --foxglove both want port {RunOptions.view_port}: give --foxglove another")
    except ValueError as exc:
        print(f"tb4 run: {exc}", file=sys.stderr)
        return 2

    if args.json:
        mode = "json"
    elif args.quiet:
        mode = "quiet"
    elif sys.stdout.isatty() and not mission.interactive:
        mode = "live"
    else:
        mode = "plain"
    tutorial_args = extra[1:] if extra[:1] == ["--"] else list(extra)
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
        time_limit=args.time_limit,
        fail_on_bump=args.fail_on_bump,
        picture=not args.no_picture,
        foxglove=foxglove,
    )
    terminated = _sigterm_as_ctrl_c()
    outcome = run_mission(mission, options)
    if terminated and outcome.exit_code == 130:
        outcome.exit_code, outcome.reason = 143, "terminated (SIGTERM): the mission and its simulator were stopped"
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
                    "run_dir": str(outcome.run_dir),
                    "bumps": len(outcome.bumps),
                }
            ),
            flush=True,
        )
    else:
        if outcome.picture is not None and mode != "quiet":
            print(f"picture of the run: {outcome.picture}")
        if outcome.mcap is not None and mode != "quiet":
            print(f"recording: {outcome.mcap}")
        if outcome.bumps and mode != "quiet":
            print(f"bumps: {len(outcome.bumps)} (marked on the picture; their times and places are in run.json)")
        verdict = "succeeded" if outcome.exit_code == 0 else f"failed: {outcome.reason}"
        print(f"tb4 run {mission.name} {verdict}")
    return outcome.exit_code


def _sigterm_as_ctrl_c() -> list[int]:
    """SIGTERM (a service manager, a container, `timeout`) stops the run as Ctrl-C does: the mission is asked to
    stop (its goal canceled), the simulator stopped, the record and picture written, and the exit code is 143.
    Installed before any rclpy context, whose own handler then calls it after shutting ROS down. The list gets the
    signal's number once it came."""
    came: list[int] = []

    def stop(signum: int, _frame: object) -> None:
        if not came:
            came.append(signum)
            raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, stop)
    return came


def register(sub: argparse._SubParsersAction) -> None:
    run = sub.add_parser(
        "run",
        help="run a tutorial or your own mission in the built-in simulator",
        description="Start the simulator, run a tutorial or your own mission (a Python script, or -m "
        "package.module, the same file that runs on the robot) against it over ROS 2, stop the simulator, and "
        "save the run folder (runs/NAME-DATE: run.png, run.json, sim.log). Arguments tb4 run does not know go to "
        "the mission; put them after -- when they share a name with ours (tb4 run mission.py --seed 3 -- --fast). "
        "The exit code is the mission's own (124: ended at --time-limit).",
    )
    run.add_argument("name", nargs="?", help="a tutorial name (see --list), a script path, or with -m a module")
    run.add_argument("-m", "--module", action="store_true", help="NAME is a module, run as python -m NAME")
    run.add_argument("--list", action="store_true", help="list the tutorials")
    run.add_argument(
        "--world", default=None, help="world name or file (default: the tutorial's own; warehouse for a mission)"
    )
    run.add_argument(
        "--robots",
        type=number("robots", 1, 64, integer=True),
        default=0,
        metavar="N",
        help="your fleet mission: robot1..robotN on the world's first N docks",
    )
    run.add_argument(
        "--time-limit",
        type=number("time limit", 0.1, 1e6),
        default=None,
        metavar="SECONDS",
        help="end the mission after this many wall seconds and record the run as timed out (exit code 124)",
    )
    run.add_argument("--no-picture", action="store_true", help="do not draw run.png (tb4 render draws it later)")
    run.add_argument(
        "--fail-on-bump", action="store_true", help="fail the run if the robot bumps into anything (exit code 1)"
    )
    run.add_argument(
        "--interactive", action="store_true", help="pass your terminal's input to your mission (plain progress)"
    )
    run.add_argument(
        "--rate",
        default="max",
        help=f"simulation speed: 1 (real time), N (N times), {RATE_MAX_HELP} (default)",
    )
    run.add_argument("--seed", type=int, default=0, help="random seed of the simulation (noise, obstacles)")
    run.add_argument("--battery", type=number("battery", 0.0, 1.0), default=None, help="start battery level, 0..1")
    run.add_argument("--namespace", default="")
    add_sensing_arguments(run)
    run.add_argument("--output-dir", default="runs", help="where run folders go (default: ./runs)")
    run.add_argument("--record", metavar="FILE.mcap", help="record the run's ROS topics to an MCAP file")
    run.add_argument("--view", action="store_true", help="serve the live web viewer during the run")
    add_foxglove_arguments(run)
    run.add_argument("--attach", action="store_true", help="use a simulator or robot that is already running")
    run.add_argument("--quiet", action="store_true", help="only the final line")
    run.add_argument("--json", action="store_true", help="one JSON event per line on stdout")
    run.add_argument("--laps", type=int, default=None, help="patrol_loop: stop after N laps")
    run.add_argument("--sim-hours", type=float, default=None, help="patrol_loop: stop after H hours of sim time")
    run.set_defaults(func=_cmd_run, takes_extra=True, exit_fast=True)  # see tb4.processes.exit_now
