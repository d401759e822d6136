"""`tb4 sim --control`'s command lines (what `tb4 sweep` sends a reused simulator on its standard input): each gets
one reply, a malformed one a refusal with the reason, and none stops the commands that follow."""

from __future__ import annotations

import io
import json
import threading
from pathlib import Path

import pytest

from tb4.processes import CONTROL_REPLY
from tb4.ros.simulator import serve_control


class _Simulator:
    """What serve_control drives: reset_world (the seed checked as the simulator checks it) and write_record."""

    def __init__(self) -> None:
        self.seed = 0
        self.resets: list[tuple[int, Path | None]] = []
        self.final_writes = 0

    def reset_world(self, seed: int | None = None, record_run: Path | None = None) -> None:
        if seed is None or not (0 <= seed < 2**32):
            raise ValueError(f"seed must be between 0 and 2**32 - 1, got {seed}")
        self.seed = seed
        self.resets.append((seed, record_run))

    def write_record(self, final: bool = False) -> Path | None:
        self.final_writes += int(final)
        return Path("/runs/run.json")


def _serve(lines: list[str]) -> tuple[list[dict], _Simulator, threading.Event]:
    simulator, stop, out = _Simulator(), threading.Event(), io.StringIO()
    serve_control(simulator, stop, io.StringIO("\n".join(lines) + "\n"), out)  # type: ignore[arg-type]
    replies = [json.loads(line.removeprefix(CONTROL_REPLY)) for line in out.getvalue().splitlines()]
    return replies, simulator, stop


@pytest.mark.parametrize(
    ("line", "error"),
    [
        ("not json", "JSONDecodeError"),
        ("[1, 2]", "AttributeError"),
        ('{"id": 1}', "unknown command"),
        ('{"id": 1, "reset": 5}', "AttributeError"),
        ('{"id": 1, "reset": {}}', "KeyError"),
        ('{"id": 1, "reset": {"seed": "five"}}', "ValueError"),
        ('{"id": 1, "reset": {"seed": NaN}}', "ValueError"),
        ('{"id": 1, "reset": {"seed": -1}}', "seed must be between"),
        ('{"id": 1, "reset": {"seed": 1e300}}', "seed must be between"),
        ('{"id": 1, "reset": {"seed": 3, "record_run": 5}}', "TypeError"),
        ('{"id": 1, "reset": {"seed": 3}}' + " " * 100_000 + "x", "JSONDecodeError"),
    ],
)
def test_a_malformed_command_is_refused_and_the_next_one_served(line: str, error: str) -> None:
    replies, simulator, stop = _serve([line, "", '{"id": 2, "reset": {"seed": 7, "record_run": "/runs/7.json"}}'])
    assert len(replies) == 2  # one reply a command; the blank line is none
    assert replies[0]["ok"] is False and error in replies[0]["error"], replies[0]
    assert replies[1] == {"ok": True, "id": 2, "seed": 7}
    assert simulator.resets == [(7, Path("/runs/7.json"))]
    assert stop.is_set()  # the end of the input stops the simulator


def test_a_write_command_names_the_record_and_writes_it_for_good() -> None:
    replies, simulator, _ = _serve(['{"id": 3, "write": true}'])
    assert replies == [{"ok": True, "id": 3, "record": "/runs/run.json"}]
    assert simulator.final_writes == 1  # the trial is over: the simulator's close must not rewrite it
