"""Run every benchmark and print one table: each figure beside the baseline measured in the same run.

make bench              # everything (a few minutes)
python bench/run.py --quick
python bench/run.py planner sim_core   # only these modules
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
import traceback
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "src"))

MODULES = ("install_startup", "sim_core", "create3", "planner", "amcl", "system", "navigator", "language", "routes")


def _fmt(value: object, unit: str) -> str:
    if isinstance(value, float):
        return f"{value:.3g} {unit}".strip()
    return f"{value} {unit}".strip() if value is not None else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("modules", nargs="*", help=f"subset of: {', '.join(MODULES)}")
    parser.add_argument("--quick", action="store_true", help="fewer repetitions")
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
            result = module.run(quick=args.quick)
        except Exception:
            failures += 1
            print(f"[bench] {name} FAILED:\n{traceback.format_exc()}", file=sys.stderr)
            continue
        for row in result:
            rows.append({"module": name, **row})
        print(f"[bench] {name} done in {time.monotonic() - start:.0f} s", file=sys.stderr, flush=True)

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
