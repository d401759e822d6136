"""What the code and its front page say must stay true on any machine, any day: no commit hash, no "stop N" of a
work log, no dated measurement in the README, the Makefile, pyproject.toml, tools/ or src/. Those belong in commit
bodies (and the benchmarks' output); the code says what is true of the code. And the README stays a front page:
short, opening with what the project is, its first commands the two CI runs.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 250
# files that are data, not text a person wrote: maps, pictures, route graphs, fonts
DATA_SUFFIXES = {".pgm", ".png", ".jpg", ".ico", ".svg", ".geojson", ".woff", ".woff2", ".so", ".mcap", ".pyc"}
_UNIT = r"(?:ms|s|us|µs|x|%|MB|GB|KB|CPU-s|min|minutes)"

PATTERNS = {
    # a 7-40 character hex word with a digit and a letter: a commit id (not a colour (#1f77b4) or a 0x constant)
    "a commit hash": re.compile(r"(?<![\w#./-])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w-])"),
    "a work log's 'stop N'": re.compile(r"\b[Ss]top \d+\b(?![.,]\d| ?(?:s|ms|m|%|x)\b)"),
    "a date": re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b"),
    "CPU seconds": re.compile(r"\bCPU-s\b"),
    "a before -> after figure": re.compile(rf"\d(?:\.\d+)? ?{_UNIT}? ?(?:->|→) ?\d[\d.,]* ?{_UNIT}\b"),
    "a measured comparison": re.compile(rf"\d(?:\.\d+)? ?{_UNIT}(?: of CPU)? (?:against|instead of) (?:about )?\d"),
    "a timing": re.compile(rf"\btook (?:about |only )?\d[\d.,]* ?{_UNIT}(?![\w-])"),
}


def _scanned() -> list[Path]:
    """The README, the Makefile, pyproject.toml and every text file under tools/ and src/ (tracked or new)."""
    roots = ["README.md", "Makefile", "pyproject.toml", "tools", "src"]
    try:
        listed = subprocess.run(
            ["git", "ls-files", "--cached", "--others", "--exclude-standard", "--", *roots],
            cwd=ROOT,
            capture_output=True,
            text=True,
            check=True,
            timeout=30,
        ).stdout.split("\n")
        files = [ROOT / name for name in listed if name]
    except (OSError, subprocess.SubprocessError):  # not a git checkout: every file
        files = [ROOT / r for r in roots[:3]] + [p for r in roots[3:] for p in (ROOT / r).rglob("*")]
    return sorted(p for p in files if p.is_file() and p.suffix not in DATA_SUFFIXES and "__pycache__" not in p.parts)


def _findings(path: Path) -> list[str]:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return []  # a binary file
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for what, pattern in PATTERNS.items():
            match = pattern.search(line)
            if match:
                found.append(f"{path.relative_to(ROOT)}:{number}: {what} ({match.group(0)!r}): {line.strip()[:100]}")
    return found


def test_no_commit_hash_work_log_or_dated_figure_in_the_code_or_the_readme() -> None:
    found = [finding for path in _scanned() for finding in _findings(path)]
    assert not found, "put these in the commit body, and keep the why here:\n" + "\n".join(found)


@pytest.mark.parametrize(
    "line",
    [
        "Latest (2026-11-27, stop 35): make test took 270.6 s at ac961ad",
        "# a collection took 4.1 to 4.7 CPU-s against 2.3 s",
        "#: about 9x less CPU (0.11 -> 0.012 s for our ten files)",
        "loading it took 6.2 ms instead of 2.7 ms",
        "a fresh clone's check took 10.6 s without it",
        "Stop 33's figures",
    ],
)
def test_the_patterns_catch_a_work_log(line: str, tmp_path: Path) -> None:
    assert any(pattern.search(line) for pattern in PATTERNS.values()), line


@pytest.mark.parametrize(
    "line",
    [
        "color: '#1f77b4'",
        "the robot stops 0.5 s after the last command",
        "# Nav2's costmap translation: 1..252 -> 1..98, 254 lethal -> 100",
        "value = 0x7fffffff",
        "announces itself every 0.5 s, not every 3 s",
        "WGS84_F = 1.0 / 298.257223563",
    ],
)
def test_the_patterns_leave_plain_facts_alone(line: str) -> None:
    assert not any(pattern.search(line) for pattern in PATTERNS.values()), line


def test_the_readme_is_a_front_page() -> None:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines: move the detail into docs/"
    assert lines[0].startswith("# ")
    opening = " ".join(lines[1 : lines.index("```bash")]).strip()
    for words in ("TurtleBot 4", "Python", "simulator", "Nav2"):
        assert words in opening, f"the README's opening paragraph should say what the project is ({words!r})"
    # its first commands are the two that CI (.ci/run: make test) and a newcomer run
    first_block = lines[lines.index("```bash") + 1 : lines.index("```", lines.index("```bash") + 1)]
    assert [line.split("#")[0].strip() for line in first_block] == ["make demo", "make test"]
