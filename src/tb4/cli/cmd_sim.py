"""`tb4 sim`: run the built-in simulator in the foreground; `tb4 render`: picture of a world."""

from __future__ import annotations

import argparse
from pathlib import Path

from tb4.cli._arguments import number
from tb4.config import ConfigError
from tb4.foxglove import add_foxglove_arguments, foxglove_options
from tb4.rosenv import apply_simulator_dds_profile, require_ros

__all__ = ["register", "RATE_MAX_HELP", "parse_rate_argument"]

#: what --rate max means, for `tb4 sim` and `tb4 run` (the figure is tb4.ros.loop.WAITING_RATE, which would bring
#: NumPy into `tb4 --help`; a test keeps the two the same)
RATE_MAX_HELP = "max (as fast as the CPU allows; 100x while every robot waits for a command)"


def parse_rate_argument(text: str) -> float:
    from tb4.ros.simulator import parse_rate  # noqa: PLC0415 - keeps `tb4 --help` free of rclpy

    try:
        return parse_rate(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_world_arguments(parser: argparse.ArgumentParser, default_world: str | None = "warehouse") -> None:
    parser.add_argument("--world", default=default_world, help="world name (warehouse, depot, maze) or world file")
    parser.add_argument(
        "--rate",
        default="1",
        type=str,
        help=f"1 = real time, N = N times real time, {RATE_MAX_HELP}",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="random seed of the noise and the obstacles: the same seed and inputs on the same ticks give the same "
        "run; over DDS the tick a command lands on varies, so live runs of one seed differ (tb4 replay re-runs a "
        "recorded run exactly)",
    )
    parser.add_argument("--namespace", default="", help="robot namespace, e.g. robot1")
    parser.add_argument("--battery", type=number("battery", 0.0, 1.0), default=None, help="start battery level, 0..1")
    add_sensing_arguments(parser)


def add_sensing_arguments(parser: argparse.ArgumentParser) -> None:
    """--exact and --localization, shared by `tb4 sim` and `tb4 run`."""
    parser.add_argument(
        "--exact", action="store_true", help="turn off odometry drift and lidar noise (on by default, seeded)"
    )
    parser.add_argument(
        "--localization",
        choices=("amcl", "truth", "odometry"),
        default="amcl",
        help="amcl (Nav2's particle filter on lidar + odometry, default), truth (the simulator's true pose) or "
        "odometry (dead reckoning from the initial pose)",
    )


def _cmd_sim(args: argparse.Namespace) -> int:
    apply_simulator_dds_profile()
    require_ros()
    from tb4.ros.simulator import SimulatorOptions, main

    try:
        rate = parse_rate_argument(args.rate)
        foxglove = foxglove_options(args)
        if foxglove is not None and args.view and foxglove.port == args.view_port:
            raise ValueError(f"--view and --foxglove both want port {args.view_port}: give --foxglove another one")
        return main(
            SimulatorOptions(
                world=args.world,
                rate=rate,
                seed=args.seed,
                namespace=args.namespace,
                robots=args.robots,
                battery=args.battery,
                record_run=Path(args.record_run) if args.record_run else None,
                record=Path(args.record) if args.record else None,
                view_port=args.view_port if args.view else None,
                hold=args.hold,
                exact=args.exact,
                localization=args.localization,
                foxglove=foxglove,
            )
        )
    except (ConfigError, ValueError, argparse.ArgumentTypeError) as exc:
        print(f"tb4 sim: {exc}")
        return 2


def _cmd_render(args: argparse.Namespace) -> int:
    from tb4.extras import MissingExtraError, require_extra
    from tb4.nav.route_graph import load_route_graph
    from tb4.sim.world import load_world

    try:
        require_extra("render")
    except MissingExtraError as exc:
        print(f"tb4 render: {exc}")
        return 2
    from tb4.sim.render import render_world

    target = Path(args.world)
    if target.is_dir() or target.suffix == ".json":
        from tb4.runner.picture import render_record

        try:
            print(render_record(target, Path(args.output) if args.output else None).resolve())
        except (OSError, ValueError, KeyError) as exc:
            print(f"tb4 render: {exc}")
            return 2
        return 0

    try:
        world = load_world(args.world)
        graph = load_route_graph(world.route_graph) if world.route_graph is not None else None
    except (ConfigError, ValueError) as exc:
        print(f"tb4 render: {exc}")
        return 2
    output = Path(args.output or f"{world.name}.png")
    render_world(world, output, title=f"world: {world.name}", route_graph=graph)
    print(output.resolve())
    return 0


def register(sub: argparse._SubParsersAction) -> None:
    sim = sub.add_parser("sim", help="run the built-in TurtleBot 4 simulator (Create 3 + Nav2 interfaces)")
    add_world_arguments(sim)
    sim.add_argument(
        "--robots",
        type=int,
        default=0,
        metavar="N",
        help="a fleet: robot1..robotN on the world's first N docks, each under its namespace (one process, one clock)",
    )
    sim.add_argument("--record-run", metavar="FILE.json", help="write what happened (trajectory, goals) on exit")
    sim.add_argument("--record", metavar="FILE.mcap", help="record the robots' ROS topics to an MCAP file")
    sim.add_argument(
        "--hold",
        action="store_true",
        help="real time until the first goal (start-up and the initial pose cost no sim time)",
    )
    sim.add_argument("--view", action="store_true", help="also serve the live web viewer (http://127.0.0.1:PORT/)")
    sim.add_argument("--view-port", type=int, default=8765, help="port of the web viewer (default 8765)")
    add_foxglove_arguments(sim)
    sim.set_defaults(func=_cmd_sim)
    render = sub.add_parser("render", help="write a PNG picture of a world, or of a run")
    render.add_argument(
        "world",
        nargs="?",
        default="warehouse",
        help="world name or world file, or a run folder (runs/NAME-DATE) or run record (run.json)",
    )
    render.add_argument("-o", "--output", help="output PNG (default: WORLD.png; a run's run.png beside its record)")
    render.set_defaults(func=_cmd_render)
