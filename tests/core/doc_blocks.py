"""The fenced code blocks of the documentation (docs/**/*.md and the README), with the test marker before each.

A marker is an HTML comment on the line right before a fence, invisible on the site and on GitHub:

    <!-- test: run -->     a Python block that runs without a simulator (in a fresh folder, after the page's files)
    <!-- test: file -->    a block written to its title="NAME" before the page's runnable blocks run
    <!-- test: world -->   a YAML block that must load as a world file (beside the shipped maps)
    <!-- test: e2e -->     a file (title="NAME") of a simulator example, run by tests/e2e/test_docs_examples.py

Every Python block compiles, marked or not. Used by tests/core/test_docs_examples.py and the e2e test.
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

__all__ = ["ROOT", "MARKERS", "Block", "pages", "blocks"]

ROOT = Path(__file__).resolve().parents[2]
MARKERS = ("run", "file", "world", "e2e")
_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,})(?P<lang>[\w+-]*)(?P<attrs>[^`\n]*)$")
_MARKER = re.compile(r"^\s*<!--\s*test:\s*(?P<marker>[\w-]+)\s*-->\s*$")
_TITLE = re.compile(r'title="(?P<title>[^"]+)"')


@dataclass(frozen=True)
class Block:
    """One fenced block: where it is, its language, its title (if any), its marker (if any) and its code."""

    page: Path
    line: int  # the fence's line, 1-based
    lang: str
    title: str
    marker: str
    code: str

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def pages() -> list[Path]:
    """Every documentation page the site or the repository shows: docs/**/*.md and the README."""
    return sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of `page`, in order (an indented fence, inside a list item, is dedented)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    i = 0
    while i < len(lines):
        opening = _FENCE.match(lines[i])
        if opening is None:
            i += 1
            continue
        indent, fence = opening["indent"], opening["fence"]
        marker = _MARKER.match(lines[i - 1]) if i else None
        title = _TITLE.search(opening["attrs"])
        end = i + 1
        while end < len(lines) and lines[end].strip() != fence:
            end += 1
        body = "\n".join(line[len(indent) :] if line.startswith(indent) else line for line in lines[i + 1 : end])
        found.append(
            Block(
                page=page,
                line=i + 1,
                lang=opening["lang"].lower(),
                title=title["title"] if title else "",
                marker=marker["marker"] if marker else "",
                code=textwrap.dedent(body) + "\n",
            )
        )
        i = end + 1
    return found
