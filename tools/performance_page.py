"""Write docs/performance.md from the benchmarks' figures (`bench/run.py --json`): every figure beside the baseline
measured in the same run, the machine and the commit it ran on, and how to reproduce it. The page is data, not
prose: it is never edited by hand, and it carries the figures it was written from, so a test can check that it is
this script's output (`--check`).

    python tools/performance_page.py --run [MODULE ...] [--quick]   # run the bench here, then write the page
    python tools/performance_page.py FIGURES.json [--machine TEXT]  # from a saved `bench/run.py --json`
    python tools/performance_page.py --check                        # exit 1 if the page is not what it renders

Without modules, --run runs every bench module but install_startup, which reinstalls the project (`make install`,
a `pip install -e .` rebuild) and so is not for a checkout that others are using; name it to include it.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

__all__ = ["PAGE", "DEFAULT_MODULES", "machine", "render", "page_data", "run_bench", "main"]

ROOT = Path(__file__).resolve().parent.parent
PAGE = ROOT / "docs" / "performance.md"
BENCH = ROOT / "bench" / "run.py"
#: what each bench module measures, in bench/run.py's order
MODULES = {
    "install_startup": "the install when nothing changed, importing tb4, and the simulator's start",
    "sim_core": "the simulator core: physics and lidar, without ROS",
    "create3": "the Create 3 base's share of a physics step",
    "planner": "the global planner on the warehouse costmap",
    "amcl": "AMCL beside the simulator's true pose, with sensor noise on",
    "system": "the whole stack over DDS: the simulator process, a navigation, `tb4 run`",
    "transport": "DDS data over loopback UDP (ours) beside Fast DDS's shared memory: the simulator, a navigation, a "
    "service's round trip and the latched map",
    "navigator": "the navigator's cost per goal, beside raw rclpy",
    "language": "the natural-language executor and the offline interpreter",
    "routes": "route planning beside grid planning, and `tb4 pose`",
    "fleet": "fleets of robots navigating in one loop",
    "sweep": "`tb4 sweep` of nav_to_pose over 200 seeds, beside a shell loop of `tb4 run` and on a local Ray head",
    "soak": "1,000 navigation goals in a row with charging: the last hundred goals beside the first hundred",
    "faults": "the fault cases of issue 40 (a killed simulator, SIGTERM, a flat battery, preemption, bad input), "
    "each beside its bound",
    "discovery": "fresh scripts started beside a running simulator and busy cores, with the simulator's Fast DDS "
    "type propagation off (as shipped) and on",
}
# install_startup reinstalls the package; sweep and soak last tens of minutes, faults kills processes and discovery
# keeps cores busy on purpose: all are run when asked for
ASKED_FOR_ONLY = ("install_startup", "sweep", "soak", "faults", "discovery")
DEFAULT_MODULES = [name for name in MODULES if name not in ASKED_FOR_ONLY]
_DATA = re.compile(r"<!-- performance-data\n(.*?)\n-->\n\Z", re.S)


def machine() -> dict[str, Any]:
    """The machine this process runs on: CPU, cores, memory, system, Python, and how busy it is now."""
    cpu = platform.processor() or platform.machine()
    memory = None
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal:"):
                memory = f"{int(line.split()[1]) / 2**20:.0f} GiB"
                break
    except OSError:
        pass
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "memory": memory,
        "system": platform.platform(terse=True),
        "python": platform.python_version(),
        "load": None if load is None else round(load[0], 2),
    }


def run_bench(modules: list[str], quick: bool) -> list[dict[str, Any]]:
    """bench/run.py --json MODULES (its progress on stderr as it goes); its rows, even when a module failed."""
    args = [sys.executable, str(BENCH), "--json", *(["--quick"] if quick else []), *modules]
    done = subprocess.run(args, cwd=ROOT, stdout=subprocess.PIPE, text=True)
    rows = json.loads(done.stdout or "[]")
    if done.returncode != 0:
        print(f"[performance] bench/run.py exited with {done.returncode}: some modules failed", file=sys.stderr)
    return rows


def page_data(rows: list[dict[str, Any]], modules: list[str], quick: bool, host: dict[str, Any]) -> dict[str, Any]:
    """What the page is written from: the rows, and where and how they were measured."""
    return {
        "commit": rows[0]["commit"] if rows else "unknown",
        "written": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": host,
        "modules": modules,
        "quick": quick,
        "rows": rows,
    }


def _number(value: Any) -> str:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    if not math.isfinite(value):
        return str(value)
    size = abs(value)
    if size < 1e-9:
        return "0"
    if float(value).is_integer():
        return f"{int(value):,}"
    if size >= 100:
        return f"{value:,.0f}"
    if size >= 10:
        return f"{value:.1f}"
    if size >= 1:
        return f"{value:.2f}"
    return f"{value:.2g}" if size < 0.01 else f"{value:.3f}".rstrip("0")


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _value(value: Any, unit: str) -> str:
    if value is None or value == "":
        return "-"
    return f"{_number(value)} {unit}".strip()


def _row(row: dict[str, Any]) -> str:
    unit = row.get("unit") or ""
    baseline = _value(row.get("baseline"), unit)
    if row.get("baseline_name") and baseline != "-":
        baseline += f" ({row['baseline_name']})"
    ratio = row.get("ratio")
    ratio_text = f"{_number(ratio)}x" if isinstance(ratio, (int, float)) and not isinstance(ratio, bool) else "-"
    cells = [row["name"], _value(row.get("value"), unit), baseline, ratio_text, str(row.get("goal") or "")]
    return "| " + " | ".join(_cell(c) for c in cells) + " |"


def _machine_line(host: dict[str, Any]) -> str:
    parts = [str(host.get("cpu") or "an unknown CPU")]
    if host.get("cores"):
        parts.append(f"{host['cores']} cores")
    if host.get("memory"):
        parts.append(str(host["memory"]))
    if host.get("system"):
        parts.append(str(host["system"]))
    if host.get("python"):
        parts.append(f"Python {host['python']}")
    line = ", ".join(parts)
    if host.get("load") is not None:
        line += f"; load average {host['load']} when the run started"
    return line


def render(data: dict[str, Any]) -> str:
    """The page (Markdown), with `data` embedded at its end."""
    commit = str(data["commit"])
    dirty = commit.endswith("-dirty")
    commit_text = f"`{commit.removesuffix('-dirty')}`" + (" with uncommitted changes" if dirty else "")
    modules = list(data["modules"])
    lines = [
        "# Performance",
        "",
        "The figures of the project's benchmarks (`bench/`), each beside a baseline measured in the same run on the "
        "same machine, so that a figure can be judged without another run. The goal column is what the figure is "
        "designed to meet. This page is written by `tools/performance_page.py` from `bench/run.py --json`; it is "
        "not edited by hand.",
        "",
        "## This run",
        "",
        f"- **Commit**: {commit_text}",
        f"- **Machine**: {_machine_line(data['machine'])}",
        f"- **Written**: {data['written']}",
        f"- **Modules**: {', '.join(f'`{m}`' for m in modules)}"
        + (" (`--quick`: fewer repetitions)" if data.get("quick") else ""),
        "",
        "The machines this project runs on are often shared and small, so a figure varies from run to run; its "
        "baseline, measured beside it, varies with it. Compare a figure with its own baseline, and figures of two "
        "commits only when they ran on the same machine.",
        "",
        "## Reproduce",
        "",
        "```bash",
        "make bench                                   # every module, as a table in the terminal",
        "python tools/performance_page.py --run       # the bench here, then this page from its figures",
        "python tools/performance_page.py --run planner sim_core --quick   # some modules, fewer repetitions",
        "python bench/run.py --json > figures.json    # or save the figures, then write the page from them:",
        "python tools/performance_page.py figures.json --machine 'the machine they ran on'",
        "```",
        "",
        "`install_startup` (the install when nothing changed, a rebuild of the project, the simulator's start) "
        "reinstalls the project, so `--run` leaves it out unless it is named; `TB4_BENCH_COLD=1` adds a cold "
        "install from a fresh clone to it. `sweep`, `soak`, `faults` and `discovery` run only when named too; all "
        "but `sweep` also run alone: `python bench/bench_soak.py --goals N` (goals between the world's places with "
        "charging, the simulator's and the navigator's memory and the time per goal, last hundred beside first "
        "hundred), `python bench/bench_faults.py` (each fault case beside its bound; it exits 1 when one is missed) "
        "and `python bench/bench_discovery.py --scripts N` (fresh scripts beside busy cores, each case with a "
        "simulator of its own).",
        "",
    ]
    rows = list(data["rows"])
    order = [m for m in MODULES if any(r["module"] == m for r in rows)]
    order += sorted({r["module"] for r in rows} - set(order))
    for module in order:
        lines += [f"## {module}", ""]
        if module in MODULES:
            lines += [MODULES[module][0].upper() + MODULES[module][1:] + ".", ""]
        lines += ["| Figure | Ours | Baseline (same run) | Ratio | Goal |", "|---|---|---|---|---|"]
        lines += [_row(r) for r in rows if r["module"] == module]
        lines.append("")
    missing = [m for m in modules if m not in order]
    if missing:
        lines += [f"No figures from {', '.join(f'`{m}`' for m in missing)} in this run (the module failed).", ""]
    lines += ["<!-- performance-data", json.dumps(data, indent=1, sort_keys=True), "-->"]
    return "\n".join(lines) + "\n"


def embedded(page: str) -> dict[str, Any]:
    """The data a page was written from (ValueError if it holds none)."""
    found = _DATA.search(page)
    if found is None:
        raise ValueError("the page holds no performance-data block: it was not written by tools/performance_page.py")
    return json.loads(found.group(1))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("figures", nargs="?", help="a saved `bench/run.py --json` output")
    parser.add_argument("--run", nargs="*", metavar="MODULE", help="run bench/run.py here (default modules: all but "
                        "install_startup, sweep, soak and faults)")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help="with --run: fewer repetitions")
    parser.add_argument("--machine", help="with FIGURES: the machine they ran on (default: this one)")
    parser.add_argument("--check", action="store_true", help="check that the page is what its data renders")
    parser.add_argument("-o", "--output", type=Path, default=PAGE, help="the page (default: docs/performance.md)")
    args = parser.parse_args(argv)
    if args.check:
        page = args.output.read_text(encoding="utf-8")
        if render(embedded(page)) != page:
            print(f"{args.output} is not what its data renders: write it with tools/performance_page.py")
            return 1
        return 0
    if (args.run is None) == (args.figures is None):
        parser.error("give either FIGURES (a saved bench/run.py --json) or --run")
    host = machine()
    if args.run is not None:
        modules = args.run or DEFAULT_MODULES
        rows = run_bench(modules, args.quick)
    else:
        rows = json.loads(Path(args.figures).read_text(encoding="utf-8"))
        modules = list(dict.fromkeys(r["module"] for r in rows))
        host = {"cpu": args.machine} if args.machine else {**host, "load": None}  # not its load now
    if not rows:
        print("[performance] no figures: the page is left as it was", file=sys.stderr)
        return 1
    args.output.write_text(render(page_data(rows, modules, args.quick, host)), encoding="utf-8")
    print(f"[performance] wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
