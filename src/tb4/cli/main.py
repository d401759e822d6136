"""Entry point of the `tb4` command: one sub-command per job, each in its own module."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from tb4.processes import end_with_parent, exit_now, restore_stop_signals, shm_snapshot
from tb4.rosenv import RosEnvironmentError, apply_safe_ros_defaults, check_ros_environment

__all__ = ["main", "build_parser"]


def _cmd_doctor(args: argparse.Namespace) -> int:
    """Report whether every ROS module we need imports."""
    checks = check_ros_environment()
    for check in checks:
        status = "ok" if check.ok else f"MISSING ({check.error})"
        print(f"{check.module:28s} {status}")
    if all(c.ok for c in checks):
        from tb4.wire import wire_format

        print(f"{'nav2_msgs wire format':28s} {wire_format()} (Nav2 {wire_format().capitalize()}'s nav2_msgs)")
        print("The ROS 2 environment is complete.")
        return 0
    print("Some ROS 2 modules are missing: re-run `make install` and read the build output.", file=sys.stderr)
    return 1


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tb4", description="TurtleBot 4 navigator and built-in simulator.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    doctor = sub.add_parser("doctor", help="check that the ROS 2 side of the install works")
    doctor.set_defaults(func=_cmd_doctor)
    _register_optional_commands(sub)
    return parser


def _register_optional_commands(sub: argparse._SubParsersAction) -> None:
    """Commands live in their own modules; each exposes register(subparsers)."""
    import importlib

    for name in ("sim", "render", "run", "replay", "sweep", "pose", "press", "kidnap", "say", "view"):
        try:
            module = importlib.import_module(f"tb4.cli.cmd_{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"tb4.cli.cmd_{name}":
                continue
            raise
        module.register(sub)


def main(argv: Sequence[str] | None = None) -> int:
    restore_stop_signals()  # Ctrl-C and SIGTERM stop every tb4 command, whoever started it
    end_with_parent()  # started by a tb4 process (a simulator under `tb4 run`): do not outlive it
    apply_safe_ros_defaults()
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    if extra and not getattr(args, "takes_extra", False):
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    # a command that says so (`exit_fast`), run as the program itself (not main([...]) from Python), ends
    # without the interpreter's finalization once it is done (exit_now)
    exit_fast = argv is None and getattr(args, "exit_fast", False)
    shm_before = args.shm_before = shm_snapshot() if exit_fast else None
    try:
        code = int((args.func(args, extra) if getattr(args, "takes_extra", False) else args.func(args)) or 0)
    except RosEnvironmentError as exc:
        print(f"tb4: {exc}", file=sys.stderr)
        return 3
    except KeyboardInterrupt:
        return 130
    if exit_fast:
        exit_now(code, shm_before)
    return code


if __name__ == "__main__":
    sys.exit(main())
