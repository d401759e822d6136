"""A sweep's results: one row per trial, written as each trial ends (JSON lines: an interrupted sweep loses
nothing), then as CSV, a summary per matrix cell (success rate with its Wilson 95 % interval, sim time p50/p95,
failures grouped by reason) and JUnit XML for CI.
"""

from __future__ import annotations

import csv
import json
import math
import re
import threading
from collections import Counter
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape, quoteattr

__all__ = ["Row", "ResultsTable", "wilson_interval", "percentile", "SUCCEEDED", "FAILED", "TIMED_OUT", "ERRORED"]

SUCCEEDED, FAILED, TIMED_OUT, ERRORED = "succeeded", "failed", "timed_out", "errored"


@dataclass
class Row:
    """One trial's result.

    Attributes:
        key: the trial's identity (tb4.sweep.matrix.Trial.key).
        index, seed, world, battery, exact, localization: its parameters.
        outcome: "succeeded", "failed", "timed_out" (ended at the time limit) or "errored" (it could not run or its
            worker died).
        reason: why, in words ("succeeded", the mission's last error, ...).
        exit_code: the mission's exit code (None when it never ran).
        sim_time, wall_time: seconds of sim time the run took, and of wall time.
        bumps: bumper presses.
        min_clearance: the closest (m) the robot's body came to a wall or obstacle away from the docks.
        localization_error: mean position error (m) of the estimate against the truth.
        replay: the command that runs this trial again: `tb4 replay RECORD` (the same run, to the bit) when its
            run folder was kept, else the `tb4 run` line with its seed and settings.
        run_dir, picture, record, mcap: what it left (failures keep theirs).
        node: the machine it ran on.
    """

    key: str
    index: int
    seed: int
    world: str
    battery: float | None
    exact: bool
    localization: str
    outcome: str
    reason: str
    exit_code: int | None = None
    sim_time: float | None = None
    wall_time: float | None = None
    bumps: int | None = None
    min_clearance: float | None = None
    localization_error: float | None = None
    replay: str = ""
    run_dir: str = ""
    picture: str = ""
    record: str = ""
    mcap: str = ""
    node: str = ""

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Row:
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in data.items() if k in names})

    @property
    def cell(self) -> tuple[str, str, bool, str]:
        return (self.world, "-" if self.battery is None else f"{self.battery:g}", self.exact, self.localization)


def wilson_interval(successes: int, trials: int, z: float = 1.959963984540054) -> tuple[float, float]:
    """The Wilson score interval of a success rate: honest at 0 %, 100 % and small counts, where the normal
    approximation gives intervals outside 0..1 or of zero width.

    Args:
        successes: trials that succeeded.
        trials: trials in all.
        z: the normal quantile (1.96 for 95 %).

    Returns:
        (low, high), within 0..1; (0, 1) for no trials.
    """
    if trials <= 0:
        return (0.0, 1.0)
    p = successes / trials
    denominator = 1.0 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    low = 0.0 if successes == 0 else max(0.0, centre - half)  # exact at the edges, where rounding would not be
    high = 1.0 if successes == trials else min(1.0, centre + half)
    return (low, high)


def percentile(values: list[float], q: float) -> float | None:
    """A percentile by linear interpolation between the closest ranks.

    Args:
        values: the sample.
        q: the percentile, 0..100.

    Returns:
        The value, or None for an empty sample.
    """
    if not values:
        return None
    ordered = sorted(values)
    position = (len(ordered) - 1) * q / 100.0
    low = int(math.floor(position))
    high = min(low + 1, len(ordered) - 1)
    return ordered[low] + (ordered[high] - ordered[low]) * (position - low)


def reason_group(reason: str) -> str:
    """A failure reason with its numbers and ids blanked, so that one cause counts once ("at (1.20, 3.40)")."""
    text = re.sub(r"\b[0-9a-f]{8}\b", "<id>", reason)
    text = re.sub(r"-?\d+(\.\d+)?", "N", text)
    return text[:200]


@dataclass
class ResultsTable:
    """The rows of a sweep, kept in `folder/results.jsonl` as they arrive."""

    folder: Path
    rows: list[Row] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    @property
    def jsonl(self) -> Path:
        return self.folder / "results.jsonl"

    @classmethod
    def load(cls, folder: Path) -> ResultsTable:
        """The rows already in a folder (an interrupted sweep's); a line cut short by a crash is skipped."""
        table = cls(Path(folder))
        if table.jsonl.is_file():
            for line in table.jsonl.read_text(encoding="utf-8").splitlines():
                try:
                    table.rows.append(Row.from_dict(json.loads(line)))
                except (ValueError, TypeError):
                    continue
        return table

    def add(self, row: Row) -> None:
        """Keep a row, and append it to results.jsonl at once (flushed: a killed sweep keeps it)."""
        with self._lock:
            self.rows.append(row)
            with self.jsonl.open("a", encoding="utf-8") as stream:
                stream.write(json.dumps(asdict(row), allow_nan=False) + "\n")

    def done_keys(self) -> set[str]:
        return {row.key for row in self.rows}

    def __iter__(self) -> Iterator[Row]:
        return iter(self.rows)

    def __len__(self) -> int:
        return len(self.rows)

    def failures(self) -> list[Row]:
        return [row for row in self.rows if row.outcome != SUCCEEDED]

    # ---------------------------------------------------------------------------------------------- outputs
    def write_csv(self, path: Path | None = None) -> Path:
        path = path or self.folder / "results.csv"
        names = [f.name for f in fields(Row)]
        with path.open("w", newline="", encoding="utf-8") as stream:
            writer = csv.DictWriter(stream, fieldnames=names)
            writer.writeheader()
            for row in sorted(self.rows, key=lambda r: r.index):
                writer.writerow(asdict(row))
        return path

    def summary(self) -> dict[str, Any]:
        """Per matrix cell and overall: trials, successes, rate with its Wilson 95 % interval, sim time p50/p95 of
        the trials that ran, outcomes, failures grouped by reason (most common first, with an example trial)."""
        cells: dict[tuple[Any, ...], list[Row]] = {}
        for row in self.rows:
            cells.setdefault(row.cell, []).append(row)
        out = [self._cell_summary(rows, cell) for cell, rows in sorted(cells.items(), key=lambda kv: str(kv[0]))]
        return {"trials": len(self.rows), "overall": self._cell_summary(self.rows, None), "cells": out}

    @staticmethod
    def _cell_summary(rows: list[Row], cell: tuple[Any, ...] | None) -> dict[str, Any]:
        successes = sum(1 for r in rows if r.outcome == SUCCEEDED)
        low, high = wilson_interval(successes, len(rows))
        sim_times = [r.sim_time for r in rows if r.sim_time is not None]
        groups: dict[str, list[Row]] = {}
        for row in rows:
            if row.outcome != SUCCEEDED:
                groups.setdefault(reason_group(row.reason), []).append(row)
        failures = [
            {"reason": members[0].reason, "count": len(members), "example": members[0].replay}
            for _, members in sorted(groups.items(), key=lambda kv: -len(kv[1]))
        ]
        summary: dict[str, Any] = {
            "trials": len(rows),
            "succeeded": successes,
            "success_rate": successes / len(rows) if rows else None,
            "wilson95": [low, high],
            "sim_time_p50": percentile(sim_times, 50),
            "sim_time_p95": percentile(sim_times, 95),
            "outcomes": dict(Counter(r.outcome for r in rows)),
            "failures": failures,
        }
        if cell is not None:
            world, battery, exact, localization = cell
            summary["cell"] = {"world": world, "battery": battery, "exact": exact, "localization": localization}
        return summary

    def write_summary(self) -> tuple[Path, str]:
        """summary.json and summary.txt; the text."""
        data = self.summary()
        (self.folder / "summary.json").write_text(json.dumps(data, indent=2, allow_nan=False), encoding="utf-8")
        text = format_summary(data)
        (self.folder / "summary.txt").write_text(text + "\n", encoding="utf-8")
        return self.folder / "summary.json", text

    def write_junit(self, path: Path, suite: str) -> Path:
        """JUnit XML: one test case per trial, a failure (or error) with the reason and the replay command.

        Args:
            path: the file to write.
            suite: the test suite's name.

        Returns:
            `path`.
        """
        rows = sorted(self.rows, key=lambda r: r.index)
        failed = sum(1 for r in rows if r.outcome in (FAILED, TIMED_OUT))
        errored = sum(1 for r in rows if r.outcome == ERRORED)
        total_time = sum(r.wall_time or 0.0 for r in rows)
        lines = [
            '<?xml version="1.0" encoding="utf-8"?>',
            f'<testsuites><testsuite name={quoteattr(suite)} tests="{len(rows)}" failures="{failed}" '
            f'errors="{errored}" time="{total_time:.3f}">',
        ]
        for row in rows:
            name = quoteattr(row.key)
            lines.append(f'<testcase classname={quoteattr(suite)} name={name} time="{row.wall_time or 0.0:.3f}">')
            if row.outcome != SUCCEEDED:
                tag = "error" if row.outcome == ERRORED else "failure"
                detail = f"{row.reason}\nreplay: {row.replay}\npicture: {row.picture}\nrecord: {row.record}"
                lines.append(f"<{tag} message={quoteattr(row.reason[:500])}>{escape(detail)}</{tag}>")
            lines.append("</testcase>")
        lines.append("</testsuite></testsuites>")
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        return path


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f} %"


def _secs(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} s"


def format_summary(summary: dict[str, Any], examples: int = 3) -> str:
    """The summary as a few lines a person reads: each cell's rate and interval, times, the commonest failures."""
    lines = []
    for entry in [*summary["cells"], summary["overall"]] if len(summary["cells"]) > 1 else summary["cells"]:
        cell = entry.get("cell")
        label = (
            "all cells"
            if cell is None
            else f"world {cell['world']}, battery {cell['battery']}, exact {cell['exact']}, {cell['localization']}"
        )
        low, high = entry["wilson95"]
        lines.append(
            f"{label}: {entry['succeeded']}/{entry['trials']} succeeded ({_pct(entry['success_rate'])}, 95 % CI "
            f"{_pct(low)}..{_pct(high)}); sim time p50 {_secs(entry['sim_time_p50'])}, "
            f"p95 {_secs(entry['sim_time_p95'])}"
        )
        for failure in entry["failures"][:examples]:
            lines.append(f"  {failure['count']} x {failure['reason']}")
            lines.append(f"      replay: {failure['example']}")
    return "\n".join(lines)
