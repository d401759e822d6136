"""The documentation's simulator example, as a reader runs it: the mission and its pytest test from the "your own
mission" guide (the blocks marked `<!-- test: e2e -->`), written to a folder of their own and run by pytest there,
so the test kit's plugin (`tb4_mission`) starts the simulator and runs the mission once. The other examples are
compiled or run without a simulator in tests/core/test_docs_examples.py.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guides" / "your-mission.md"


def _doc_blocks():  # tests/core/doc_blocks.py, the one reader of the docs' code blocks
    spec = importlib.util.spec_from_file_location("doc_blocks", ROOT / "tests" / "core" / "doc_blocks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("doc_blocks", module)
    spec.loader.exec_module(module)
    return module


def test_the_guides_mission_passes_the_guides_test(tmp_path: Path) -> None:
    files = [block for block in _doc_blocks().blocks(GUIDE) if block.marker == "e2e"]
    assert {block.title for block in files} == {"my_mission.py", "test_my_mission.py"}
    for block in files:
        (tmp_path / block.title).write_text(block.code, encoding="utf-8")
    installed = any(ep.name == "tb4" for ep in importlib.metadata.entry_points(group="pytest11"))
    plugin = [] if installed else ["-p", "tb4.testing.plugin"]  # an editable install made before the entry point
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTEST_", "TB4_TEST"))}
    pytest_command = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *plugin, "-q", "--basetemp", "tmp"]
    proc = subprocess.run(
        [*pytest_command, "test_my_mission.py"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0 and "1 passed" in proc.stdout, proc.stdout[-3000:] + proc.stderr[-2000:]
