"""Helpers for the end-to-end tests: run `tb4 run` as a user would and read what it left behind."""

from __future__ import annotations

import json
import math
import os
import pty
import select
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from tb4.processes import ros_environment, tb4_command

TB4 = tb4_command()


def environment() -> dict[str, str]:
    return ros_environment(int(os.environ["ROS_DOMAIN_ID"]))


def run_json(
    args: list[str], out_dir: Path, timeout: float = 300, mission_args: list[str] | None = None
) -> tuple[int, list[dict[str, Any]], str]:
    """`tb4 run ... --json [-- MISSION_ARGS]`: exit code, the JSON events, stderr."""
    after = ["--", *mission_args] if mission_args is not None else []
    proc = subprocess.run(
        [*TB4, "run", *args, "--json", "--output-dir", str(out_dir), *after],
        env=environment(),
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )
    if proc.returncode != 0:  # whole, in the report's captured output (an assertion message is cut short)
        sys.stderr.write(f"tb4 run {' '.join(args)}: exit code {proc.returncode}, stderr:\n{proc.stderr}")
        sys.stderr.write("its last events:\n" + "\n".join(proc.stdout.splitlines()[-30:]))
        # the simulator's side of a failure (a goal it rejected, a callback that failed) is only in its log, in a
        # run folder pytest deletes a few sessions later
        for log in sorted(out_dir.glob("*/sim.log")):
            sys.stderr.write(f"\n{log}:\n{log.read_text(errors='replace')[-6000:]}")
    events = [json.loads(line) for line in proc.stdout.splitlines() if line.strip()]
    return proc.returncode, events, proc.stderr


def record_of(events: list[dict[str, Any]]) -> dict[str, Any]:
    end = events[-1]
    assert end["event"] == "end", end
    assert end["record"], end
    return json.loads(Path(end["record"]).read_text())


def assert_replays_exactly(events: list[dict[str, Any]]) -> None:
    """`tb4 replay`'s engine, in this process: the run's journal holds every input it depended on, and re-running
    it with no DDS gives the recorded trajectory to the bit."""
    from tb4.replay.engine import replay

    record = record_of(events)
    assert record["replay"]["untracked"] == [], record["replay"]
    report = replay(Path(events[-1]["record"]))
    assert report.identical and report.input_errors == [], report.summary()


# Where the robot truly stops: Nav2's xy_goal_tolerance (0.25 m) is checked on the AMCL estimate, which is up to
# 0.15 m off in these runs (the run record's localization_error), so the true pose may be 0.4 m from the goal.
GOAL_REACHED = 0.4


def visits_in_order(
    record: dict[str, Any], goals: list[tuple[float, float]], tolerance: float = GOAL_REACHED
) -> list[int]:
    """Trajectory indices where the robot came within `tolerance` of each goal, each after the previous one.
    Raises AssertionError naming the first goal never reached in order."""
    trajectory = record["trajectory"]
    indices, start = [], 0
    for k, (gx, gy) in enumerate(goals):
        for i in range(start, len(trajectory)):
            _, x, y, _ = trajectory[i]
            if math.hypot(x - gx, y - gy) <= tolerance:
                indices.append(i)
                start = i
                break
        else:
            closest = min(math.hypot(p[1] - gx, p[2] - gy) for p in trajectory[start:]) if trajectory[start:] else None
            raise AssertionError(f"goal {k} ({gx}, {gy}) not reached in order (closest {closest})")
    return indices


def results(record: dict[str, Any], action: str) -> list[str]:
    return [e["status"] for e in record["events"] if e["type"] == "result" and e["action"] == action]


class Terminal:
    """`tb4 run NAME` in a pseudo-terminal: read its screen output, type into it."""

    def __init__(self, args: list[str], out_dir: Path) -> None:
        self.master, slave = pty.openpty()
        self.proc = subprocess.Popen(
            [*TB4, "run", *args, "--output-dir", str(out_dir)],
            env=environment(),
            stdin=slave,
            stdout=slave,
            stderr=slave,
            start_new_session=True,
        )
        os.close(slave)
        self.output = ""

    def read_until(self, text: str, timeout: float = 60, count: int = 1) -> str:
        """Read until `text` has appeared `count` times in the whole output."""
        deadline = time.monotonic() + timeout
        while self.output.count(text) < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"timed out waiting for {text!r}; output so far:\n{self.output[-3000:]}")
            ready, _, _ = select.select([self.master], [], [], min(remaining, 0.2))
            if ready:
                try:
                    chunk = os.read(self.master, 65536)
                except OSError:  # the program closed its terminal
                    chunk = b""
                if not chunk:
                    if self.proc.poll() is not None:
                        raise AssertionError(f"program ended before {text!r}:\n{self.output[-3000:]}")
                    continue
                self.output += chunk.decode(errors="replace")
        return self.output

    def type(self, text: str) -> None:
        os.write(self.master, text.encode())

    def wait(self, timeout: float = 120) -> int:
        deadline = time.monotonic() + timeout
        while self.proc.poll() is None and time.monotonic() < deadline:
            ready, _, _ = select.select([self.master], [], [], 0.2)
            if ready:
                try:
                    self.output += os.read(self.master, 65536).decode(errors="replace")
                except OSError:
                    break
        return self.proc.wait(timeout=max(1.0, deadline - time.monotonic()))

    def close(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(timeout=5)
        os.close(self.master)
