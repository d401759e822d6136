"""Run every benchmark and print one table: each figure beside the baseline measured in the same run.

make bench              # everything (a few minutes)
python bench/run.py --quick
python bench/run.py planner sim_core   # only these modules
python bench/run.py --json > figures.json   # machine-readable, to compare figures between commits
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import math
import subprocess
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "src"))

MODULES = (
    "install_startup",
    "sim_core",
    "create3",
    "planner",
    "amcl",
    "system",
    "transport",
    "navigator",
    "language",
    "routes",
    "fleet",
    "sweep",
    "soak",
    "faults",
    "burst",
    "discovery",
)


def _fmt(value: object, unit: str) -> str:
    if isinstance(value, float):
        return f"{value:.3g} {unit}".strip()
    return f"{value} {unit}".strip() if value is not None else "-"


def commit() -> str:
    """The checkout's commit, with "-dirty" when files differ from it ("unknown" outside git)."""
    try:
        head = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=HERE, capture_output=True, text=True, check=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=HERE,
            capture_output=True,
            text=True,
            timeout=10,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return head + ("-dirty" if dirty else "")


def _number(value: object) -> float | int | str | None:
    """JSON-safe: inf and nan (which JSON cannot hold) as strings."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    return value  # type: ignore[return-value]


def json_rows(rows: list[dict], at_commit: str) -> list[dict]:
    """One object per figure: name, value, unit, baseline (and what it is), ratio, goal, module, commit."""
    return [
        {
            "name": r["name"],
            "module": r["module"],
            "value": _number(r.get("ours")),
            "unit": r.get("unit", ""),
            "baseline": _number(r.get("baseline")),
            "baseline_name": r.get("baseline_name"),
            "ratio": _number(r.get("ratio")),
            "goal": r.get("goal"),
            "commit": at_commit,
        }
        for r in rows
    ]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("modules", nargs="*", help=f"subset of: {', '.join(MODULES)}")
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON instead of a table")
    args = parser.parse_args(argv)
    selected = args.modules or list(MODULES)
    rows: list[dict] = []
    failures = 0
    for name in selected:
        try:
            module = importlib.import_module(f"bench_{name}")
        except ModuleNotFoundError as exc:
            print(f"[bench] {name}: not available ({exc})", file=sys.stderr)
            continue
        start = time.monotonic()
        print(f"[bench] running {name} ...", file=sys.stderr, flush=True)
        try:
            # with --json, stdout holds the JSON alone: the modules' notes go to stderr
            with contextlib.redirect_stdout(sys.stderr if args.json else sys.stdout):
                result = module.run(quick=args.quick)
        except Exception:
            failures += 1
            print(f"[bench] {name} FAILED:\n{traceback.format_exc()}", file=sys.stderr)
            continue
        for row in result:
            rows.append({"module": name, **row})
            if row.get("passed") is False:  # a figure that missed its bound (the fault cases say so)
                failures += 1
                print(f"[bench] {name}: missed its bound: {row['name']}", file=sys.stderr)
        print(f"[bench] {name} done in {time.monotonic() - start:.0f} s", file=sys.stderr, flush=True)

    if args.json:
        json.dump(json_rows(rows, commit()), sys.stdout, indent=1)
        print()
        return 1 if failures else 0
    headers = ("benchmark", "ours", "baseline", "ratio", "goal")
    table = [
        (
            r["name"],
            _fmt(r.get("ours"), r.get("unit", "")),
            _fmt(r.get("baseline"), r.get("unit", "")) + (f" ({r['baseline_name']})" if r.get("baseline_name") else ""),
            f"{r['ratio']:.1f}x" if isinstance(r.get("ratio"), (int, float)) else "-",
            str(r.get("goal", "")),
        )
        for r in rows
    ]
    widths = [max(len(h), *(len(row[i]) for row in table)) if table else len(h) for i, h in enumerate(headers)]
    print("  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for row in table:
        print("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=True)))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
