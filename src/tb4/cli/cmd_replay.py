"""`tb4 replay RUN`: re-run a recorded run from its input journal, with no DDS, and say whether it is the same."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from tb4.replay.engine import ReplayReport

__all__ = ["register"]

DESCRIPTION = """\
Re-run a recorded run (a `tb4 run` folder, its run.json, or a `tb4 sim --record-run` record) in this process,
with no DDS: the world is rebuilt from the run's seed and settings, and every input the simulator received
(goals, cancels, velocity commands, initial poses, button presses, ...) is applied on the tick it was applied
live. The replayed trajectory is compared with the recording's, every robot's pose after every tick to the bit.

Why two live runs of one seed differ: the seed fixes the world, the sensor noise and the moving obstacles, but an
input reaches the simulator over DDS, and the tick it lands on depends on the machine's timing (process start,
discovery, scheduling). One tick earlier or later and the robot takes a slightly different path. The journal
records those ticks, so a replay is exact.

Exit status: 0 the replay is the recording bit for bit; 1 it differs (it says where); 2 the run cannot be
replayed (no journal, a malformed one, a world that is gone).

To watch or record it, --view and --record replay the run in a simulator process instead, which serves it over
ROS 2 as `tb4 sim` does (on loopback, in this shell's ROS_DOMAIN_ID) for the web viewer and an MCAP recording,
and stops after the run's last tick. The check above is the in-process replay's; run it without --view/--record.
"""


def _cmd_replay(args: argparse.Namespace) -> int:
    from tb4.config import ConfigError
    from tb4.replay.engine import ReplayError, replay
    from tb4.replay.journal import JournalError

    if args.view or args.record:
        return _serve_replay(args)
    try:
        report = replay(Path(args.run))
    except (ReplayError, JournalError, ConfigError) as exc:
        print(f"tb4 replay: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(report.to_json()))
    else:
        print(report.summary())
        for reason in report.untracked:
            print(f"  not in the journal: {reason}")
        for reason in report.left_out:
            print(f"  left out (no effect on motion, not re-simulated): {reason}")
        if not report.reproducible:
            print("  the run used inputs replay cannot redo, so it is not reproducible from its journal")
        for error in report.input_errors[:10]:
            print(f"  refused input (as live): {error}")
    if args.picture:
        picture = _draw(report, Path(args.picture))
        if picture is None:
            return 2
        if not args.json:
            print(f"picture: {picture}")
    return 0 if report.identical else 1


def _serve_replay(args: argparse.Namespace) -> int:
    """The replay in a simulator process of its own (this one): the viewer and the recorder see it over ROS 2."""
    from tb4.cli.cmd_sim import parse_rate_argument
    from tb4.config import ConfigError
    from tb4.replay.engine import ReplayError, find_journal, world_settings
    from tb4.replay.journal import JournalError, read_journal
    from tb4.rosenv import apply_simulator_dds_profile, require_ros

    try:
        path = find_journal(Path(args.run))
        world, settings, _ = world_settings(read_journal(path))
        rate = parse_rate_argument(args.rate)
    except (ReplayError, JournalError, ConfigError, argparse.ArgumentTypeError) as exc:
        print(f"tb4 replay: {exc}", file=sys.stderr)
        return 2
    apply_simulator_dds_profile()
    require_ros()
    from tb4.ros.simulator import SimulatorOptions, main

    return main(
        SimulatorOptions(
            world=str(world.source),
            rate=rate,
            seed=settings.seed,
            namespace=settings.namespace,
            robots=settings.robots,
            battery=settings.battery,
            physics_dt=settings.physics_dt,
            exact=settings.exact,
            localization=settings.localization,
            record=Path(args.record) if args.record else None,
            view_port=args.view_port if args.view else None,
            replay=path,
        )
    )


def _draw(report: ReplayReport, output: Path) -> Path | None:
    """The replayed trajectory on its world (the [render] extra)."""
    import numpy as np

    from tb4.extras import MissingExtraError, require_extra
    from tb4.replay.journal import read_journal
    from tb4.sim.world import load_world

    try:
        require_extra("render")
    except MissingExtraError as exc:
        print(f"tb4 replay: {exc}", file=sys.stderr)
        return None
    from tb4.sim.render import render_world

    settings = read_journal(report.journal).settings
    world_file = settings.get("world_file")
    world = load_world(world_file if world_file and Path(world_file).is_file() else settings["world"])
    trajectory = np.asarray(report.trajectory, dtype=float).reshape(-1, 4)
    last = trajectory[-1] if len(trajectory) else None
    return render_world(
        world,
        output,
        trajectory=trajectory[:, :3] if len(trajectory) >= 2 else None,
        robot_pose=(float(last[1]), float(last[2]), float(last[3])) if last is not None else None,
        title=f"replay of {report.journal.parent.name}",
        obstacle_time=float(last[0]) if last is not None else 0.0,
    )


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "replay",
        help="re-run a recorded run from its input journal (no DDS) and check it is the same, bit for bit",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("run", help="a run folder (runs/NAME-DATE), its run.json, or a journal (run.inputs.jsonl)")
    parser.add_argument("--json", action="store_true", help="print the report as one JSON object")
    parser.add_argument("--picture", metavar="FILE.png", help="draw the replayed trajectory on its world")
    parser.add_argument(
        "--view", action="store_true", help="watch the replay in the web viewer (a simulator serves it)"
    )
    parser.add_argument("--view-port", type=int, default=8765, help="port of the web viewer (default 8765)")
    parser.add_argument("--record", metavar="FILE.mcap", help="record the replay's ROS topics to an MCAP file")
    parser.add_argument(
        "--rate", default="1", help="with --view/--record: 1 = real time, N = N times real time, max (default 1)"
    )
    parser.set_defaults(func=_cmd_replay)
