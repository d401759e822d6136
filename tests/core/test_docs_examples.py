"""The documentation's code examples run in the tests, so they cannot rot (markers: tests/core/doc_blocks.py).

Every Python block of docs/**/*.md and the README compiles; the blocks marked to run, run here without a simulator,
each in a fresh folder holding its page's file blocks; world-file examples load. The simulator example (the blocks
marked e2e) runs in tests/e2e/test_docs_examples.py.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from doc_blocks import MARKERS, ROOT, Block, blocks, pages

pytestmark = pytest.mark.core

EVERY_BLOCK = [block for page in pages() for block in blocks(page)]
PYTHON = [block for block in EVERY_BLOCK if block.lang in ("python", "py")]
RUNNABLE_PAGES = sorted({block.page for block in EVERY_BLOCK if block.marker == "run"})
WORLDS = [block for block in EVERY_BLOCK if block.marker == "world"]


@pytest.mark.parametrize("block", PYTHON, ids=[block.where for block in PYTHON])
def test_every_python_example_compiles(block: Block) -> None:
    compile(block.code, block.where, "exec")


def test_the_markers_are_known_and_say_what_they_need() -> None:
    for block in EVERY_BLOCK:
        assert block.marker in ("", *MARKERS), f"{block.where}: unknown test marker {block.marker!r}"
        if block.marker in ("file", "e2e"):
            assert block.title, f'{block.where}: a {block.marker} block needs title="NAME" (the file it is)'
        if block.marker == "run":
            assert block.lang == "python", f"{block.where}: only Python blocks run"
        if block.marker == "world":
            assert block.lang == "yaml", f"{block.where}: a world is a YAML block"
    # the examples the tests lean on are still there
    assert RUNNABLE_PAGES and WORLDS
    e2e = {block.title for block in EVERY_BLOCK if block.marker == "e2e"}
    assert {"my_mission.py", "test_my_mission.py"} <= e2e


@pytest.mark.parametrize("page", RUNNABLE_PAGES, ids=[str(p.relative_to(ROOT)) for p in RUNNABLE_PAGES])
def test_the_runnable_examples_run(page: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("TB4_DESTINATIONS", raising=False)
    page_blocks = blocks(page)
    for block in page_blocks:
        if block.marker == "file":
            (tmp_path / block.title).write_text(block.code, encoding="utf-8")
    for block in page_blocks:
        if block.marker == "run":
            namespace = {"__name__": "__docs_example__"}
            exec(compile(block.code, block.where, "exec"), namespace)  # noqa: S102 - our own documentation


@pytest.mark.parametrize("block", WORLDS, ids=[block.where for block in WORLDS])
def test_the_world_examples_load(block: Block, tmp_path: Path) -> None:
    from tb4.sim.world import WORLDS_DIR, load_world

    for shipped in WORLDS_DIR.iterdir():  # the maps and route graphs an example may name
        if shipped.is_file():
            shutil.copy(shipped, tmp_path / shipped.name)
    path = tmp_path / (block.title or "example.yaml")
    path.write_text(block.code, encoding="utf-8")
    world = load_world(path)
    assert world.source == path and os.path.samefile(world.map_path.parent, tmp_path)
