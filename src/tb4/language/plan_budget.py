"""The planner's budgets: evaluation steps, a deadline, and the size of every value as it is built.

The deadline is the planning thread's CPU time (what the program costs), with a wall-clock backstop
(`max_plan_wall_seconds`, ten times as long by default): on a machine busy with other work (a robot running Nav2,
a test run beside two busy loops) a thread can wait for a core longer than planning takes, and a valid program was
refused for it; a run starved of CPU, or blocked in a pose check, still ends at the backstop.

Per-list checks alone miss sharing: ``A1 = [A0, A0, A0, A0]``, ..., ``A20 = [A19, ...]`` has only four elements
per list but 4^21 leaves, and anything that walks it (formatting, comparing, copying) never ends. So each value
gets a size in cells when it is built, from the sizes of its parts (a part reachable twice counts twice), and a
value over `max_value_cells` is refused before it exists for the program. The cells allocated by the program in
total (`max_total_cells`) bound the planner's memory. Sizes are remembered per object, so measuring a new list
costs one look-up per element, never a walk of what it contains.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

from tb4.language.bounded_format import bounded_repr
from tb4.language.limits import Limits
from tb4.language.vocabulary import ProgramRejected

__all__ = ["Budget"]


class Budget:
    """Counts work, time and cells for one planning run; every check raises ProgramRejected when exceeded."""

    def __init__(
        self,
        limits: Limits,
        clock: Callable[[], float] = time.thread_time,
        wall_clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.limits = limits
        self.clock = clock
        self.wall_clock = wall_clock
        self.deadline = clock() + limits.max_plan_seconds
        self.wall_deadline = wall_clock() + limits.max_plan_wall_seconds
        self.ops = 0
        self.cells = 0
        # id(value) -> (value, cells, depth); the value is kept so its id stays unique while we plan.
        self._known: dict[int, tuple[Any, int, int]] = {}

    def tick(self, line: int = 0) -> None:
        """One evaluation step: refuse once the step budget or the deadline is spent."""
        self.ops += 1
        if self.ops > self.limits.max_eval_ops:
            raise ProgramRejected(f"program does too much work (more than {self.limits.max_eval_ops} steps)", line)
        self.check_deadline(line)

    def check_deadline(self, line: int = 0) -> None:
        if self.clock() > self.deadline:
            raise ProgramRejected(f"planning took longer than {self.limits.max_plan_seconds:g} s", line)
        if self.wall_clock() > self.wall_deadline:
            raise ProgramRejected(
                f"planning took longer than {self.limits.max_plan_wall_seconds:g} s of wall time", line
            )

    # -- sizes ----------------------------------------------------------------------------------------------
    def measure(self, value: Any) -> tuple[int, int]:
        """(cells, depth) of a value; containers must have been admitted (or be made of admitted parts)."""
        if isinstance(value, str):
            return 1 + len(value), 0
        if not isinstance(value, (list, tuple, dict)):
            return 1, 0
        known = self._known.get(id(value))
        if known is not None and known[0] is value:
            return known[1], known[2]
        return self._measure_new(value, 0)

    def _measure_new(self, value: Any, level: int) -> tuple[int, int]:
        if level > self.limits.max_value_depth:
            raise ProgramRejected(f"value nested too deeply (limit {self.limits.max_value_depth})")
        parts = list(value.items()) if isinstance(value, dict) else value
        cells, depth = 1, 0
        for part in parts:
            for item in part if isinstance(value, dict) else (part,):
                known = self._known.get(id(item)) if isinstance(item, (list, tuple, dict)) else None
                if known is not None and known[0] is item:
                    c, d = known[1], known[2]
                elif isinstance(item, (list, tuple, dict)):
                    c, d = self._measure_new(item, level + 1)
                else:
                    c, d = self.measure(item)
                cells += c
                depth = max(depth, d + 1)
                if cells > self.limits.max_value_cells:
                    raise ProgramRejected(
                        f"value too large: more than {self.limits.max_value_cells} cells "
                        "(elements reachable several times count each time)"
                    )
        self._known[id(value)] = (value, cells, depth)
        return cells, depth

    def admit(self, value: Any, line: int = 0) -> Any:
        """Check a value the program just built (a number, a string, a list, ...) and return it."""
        lim = self.limits
        if isinstance(value, bool) or value is None:
            return value
        if isinstance(value, (int, float)):
            if isinstance(value, float) and not math.isfinite(value):
                raise ProgramRejected(f"number is not finite ({value})", line)
            if abs(value) > lim.max_abs_number:
                raise ProgramRejected(
                    f"number {bounded_repr(value, 40)} is too large (limit {lim.max_abs_number:g})", line
                )
            return value
        if isinstance(value, str):
            if len(value) > lim.max_string:
                raise ProgramRejected(f"string too long ({len(value)} characters, limit {lim.max_string})", line)
            self._allocate(len(value), line)
            return value
        if isinstance(value, (list, tuple, dict)):
            if len(value) > lim.max_list:
                raise ProgramRejected(f"list too long ({len(value)} elements, limit {lim.max_list})", line)
            self._allocate(1 + len(value) * (2 if isinstance(value, dict) else 1), line)
            try:
                _cells, depth = self.measure(value)
            except ProgramRejected as exc:
                raise ProgramRejected(exc.reason, line) from None
            if depth > lim.max_value_depth:
                raise ProgramRejected(f"value nested too deeply (limit {lim.max_value_depth})", line)
            return value
        return value

    def _allocate(self, cells: int, line: int) -> None:
        self.cells += cells
        if self.cells > self.limits.max_total_cells:
            raise ProgramRejected(
                f"program builds too much data (more than {self.limits.max_total_cells} cells in all)", line
            )
