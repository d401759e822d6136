"""The trials of a sweep: every combination of seeds, worlds, start batteries and sensing settings.

A trial is identified by its parameters (`Trial.key`), so a resumed sweep knows which trials are done whatever
order they finished in, and two sweeps of different matrices are told apart.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

__all__ = ["Trial", "build_matrix", "parse_seeds", "parse_list", "MAX_TRIALS"]

MAX_TRIALS = 1_000_000  # a sweep larger than this is a typo (0:10000000), not a plan


@dataclass(frozen=True)
class Trial:
    """One run of the mission: its place in the sweep and the simulator settings it runs with."""

    index: int
    seed: int
    world: str
    battery: float | None = None
    exact: bool = False
    localization: str = "amcl"

    @property
    def key(self) -> str:
        """What identifies the trial in a results table (not its index: a resumed sweep may order differently)."""
        battery = "-" if self.battery is None else f"{self.battery:g}"
        return f"seed={self.seed} world={self.world} battery={battery} exact={int(self.exact)} loc={self.localization}"

    @property
    def cell(self) -> tuple[str, str, bool, str]:
        """The matrix cell the trial belongs to: every parameter but the seed."""
        return (self.world, "-" if self.battery is None else f"{self.battery:g}", self.exact, self.localization)

    def as_dict(self) -> dict[str, object]:
        return asdict(self)


def parse_seeds(text: str) -> list[int]:
    """Seeds from "0:1000" (0 to 999), "5" or "1,4,9" (and mixes: "0:10,42").

    Raises:
        ValueError: not seeds, an empty or reversed range, a negative seed, or more than MAX_TRIALS.
    """
    seeds: list[int] = []
    for part in (p.strip() for p in text.split(",")):
        if not part:
            raise ValueError(f"empty seed in {text!r}")
        try:
            if ":" in part:
                start_text, stop_text = part.split(":", 1)
                start, stop = int(start_text), int(stop_text)
                if stop <= start:
                    raise ValueError(f"seed range {part!r} is empty (START:STOP runs START..STOP-1)")
                if stop - start > MAX_TRIALS:
                    raise ValueError(f"seed range {part!r} has more than {MAX_TRIALS:,} seeds")
                seeds.extend(range(start, stop))
            else:
                seeds.append(int(part))
        except ValueError as exc:
            if "seed range" in str(exc):
                raise
            raise ValueError(f"seeds must be N, START:STOP or a comma list of them, got {part!r}") from None
    if any(seed < 0 or seed >= 2**32 for seed in seeds):
        raise ValueError("seeds must be between 0 and 2**32 - 1")
    return list(dict.fromkeys(seeds))


def parse_list(text: str, what: str) -> list[str]:
    """A comma list ("warehouse,depot"), each item once, none empty.

    Raises:
        ValueError: an empty item.
    """
    items = [item.strip() for item in text.split(",")]
    if not all(items):
        raise ValueError(f"{what}: empty item in {text!r}")
    return list(dict.fromkeys(items))


def build_matrix(
    seeds: Sequence[int],
    worlds: Sequence[str],
    batteries: Sequence[float | None] = (None,),
    exact: Iterable[bool] = (False,),
    localizations: Sequence[str] = ("amcl",),
) -> list[Trial]:
    """Every combination, seeds innermost (a partial sweep covers every cell a little).

    Raises:
        ValueError: an empty axis, a battery outside 0..1, or more than MAX_TRIALS trials.
    """
    axes = {"seeds": seeds, "worlds": worlds, "batteries": batteries, "localizations": localizations}
    for name, axis in axes.items():
        if not axis:
            raise ValueError(f"no {name} to sweep over")
    for battery in batteries:
        if battery is not None and not (0.0 <= battery <= 1.0):
            raise ValueError(f"battery must be between 0 and 1, got {battery}")
    flags = list(dict.fromkeys(exact))
    count = len(seeds) * len(worlds) * len(batteries) * len(flags) * len(localizations)
    if count > MAX_TRIALS:
        raise ValueError(f"{count:,} trials: more than {MAX_TRIALS:,}")
    trials = []
    for index, (world, battery, flag, localization, seed) in enumerate(
        itertools.product(worlds, batteries, flags, localizations, seeds)
    ):
        trials.append(Trial(index, seed, world, battery, flag, localization))
    return trials
