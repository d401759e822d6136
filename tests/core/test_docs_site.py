"""The documentation site's generated and checked parts: the CLI reference written from the `tb4` parsers, the world
file reference against the loader's keys, the API reference's targets, the performance page against its data, and
the docs build in `make test` and its install.

(`make docs` builds the whole site with --strict: a broken link or an unresolved reference fails it there.)
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import yaml

from tool_modules import load_tool

pytestmark = pytest.mark.core

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"


def _nav_pages(nav: list) -> list[str]:
    pages: list[str] = []
    for entry in nav:
        for value in entry.values() if isinstance(entry, dict) else [entry]:
            pages += _nav_pages(value) if isinstance(value, list) else [value]
    return pages


# ---------------------------------------------------------------------------------------------- the CLI reference
def test_the_cli_reference_has_every_command_and_option_and_is_not_committed() -> None:
    from tb4.cli.main import build_parser

    hooks = load_tool("mkdocs_hooks")
    page = hooks.cli_reference()
    for name, _summary, sub in hooks.subcommands(build_parser()):
        assert f"\n## tb4 {name}\n" in page and f"(#tb4-{name})" in page
        for action in sub._actions:
            for option in [] if action.dest == "help" else action.option_strings:
                assert f"`{option}" in page, (name, option)
    assert "`--time-limit SECONDS`" in page and "`--allow-host NAME`" in page
    assert not (DOCS / hooks.CLI_PAGE).exists(), "the CLI reference is generated at build time, never committed"
    nav = yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"]
    assert hooks.CLI_PAGE in _nav_pages(nav)


def test_the_hook_adds_the_page_to_the_site() -> None:
    pytest.importorskip("mkdocs", reason="the [docs] extra is not installed")
    from mkdocs.config import load_config
    from mkdocs.structure.files import Files

    config = load_config(str(ROOT / "mkdocs.yml"))  # its hooks are plugins, run by the site's own event
    files = config.plugins.on_files(Files([]), config=config)
    page = files.get_file_from_path("reference/cli.md")
    assert page is not None and page.content_string.startswith("# CLI reference")


# -------------------------------------------------------------------------------------------- the other pages
def test_every_page_in_the_nav_exists_and_every_page_is_in_it() -> None:
    nav = _nav_pages(yaml.safe_load((ROOT / "mkdocs.yml").read_text())["nav"])
    generated = {load_tool("mkdocs_hooks").CLI_PAGE}
    assert [p for p in nav if p not in generated and not (DOCS / p).is_file()] == []
    written = {str(p.relative_to(DOCS)) for p in DOCS.rglob("*.md")}
    assert written - set(nav) == set(), "a page the navigation does not reach"


def test_the_world_file_reference_describes_every_key_the_loader_takes() -> None:
    from tb4.core import maps
    from tb4.sim import fleet_spec, world

    page = (DOCS / "reference" / "world-schema.md").read_text()
    keys = {
        "world": world._WORLD_KEYS,
        "destination": world._DESTINATION_KEYS,
        "obstacle": world._OBSTACLE_KEYS,
        "robot": fleet_spec._ROBOT_KEYS,
        "map": maps._MAP_KEYS,
    }
    for kind, names in keys.items():
        for name in names:
            assert re.search(rf"^\| `{name}` \|", page, re.M), f"the {kind} key {name!r} has no row in the reference"
    for shape in world._SHAPES + world._MODES:
        assert f"`{shape}`" in page


def _defined(source: Path, name: str) -> bool:
    tree = ast.parse(source.read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.name == name:
            return True
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == name for t in node.targets):
            return True
        if isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.target.id == name:
            return True
    return False


def test_every_api_reference_names_an_object_of_the_sources() -> None:
    targets = [
        (page, match)
        for page in DOCS.rglob("*.md")
        for match in re.findall(r"^::: ([\w.]+)$", page.read_text(encoding="utf-8"), re.M)
    ]
    assert len(targets) > 20
    for page, dotted in targets:
        parts = dotted.split(".")
        for split in range(len(parts), 0, -1):
            module = ROOT / "src" / Path(*parts[:split])
            source = module / "__init__.py" if module.is_dir() else module.with_suffix(".py")
            if source.is_file():
                break
        else:
            pytest.fail(f"{page.name}: {dotted}: no such module under src/")
        rest = parts[split:]
        assert len(rest) <= 1, f"{page.name}: {dotted}: reference a module or a top-level object"
        if rest:
            assert _defined(source, rest[0]), f"{page.name}: {dotted}: {rest[0]} is not defined in {source.name}"


# ------------------------------------------------------------------------------------------ the performance page
def test_the_performance_page_is_the_scripts_output() -> None:
    script = load_tool("performance_page")
    page = (DOCS / "performance.md").read_text(encoding="utf-8")
    data = script.embedded(page)
    assert script.render(data) == page, "docs/performance.md was edited by hand: write it with the script"
    assert data["rows"] and data["commit"] and data["machine"]


def test_the_performance_page_shows_every_figure_beside_its_baseline(tmp_path: Path) -> None:
    script = load_tool("performance_page")
    rows = [
        {"module": "planner", "name": "cross-warehouse plan", "value": 6.88, "unit": "ms", "baseline": 421.8,
         "baseline_name": "same A* in pure Python", "ratio": 61.3, "goal": "<= 20 ms", "commit": "abc1234-dirty"},
        {"module": "amcl", "name": "global localization", "value": "9 of 10 seeds", "unit": "", "baseline": None,
         "baseline_name": None, "ratio": None, "goal": ">= 8 of 10", "commit": "abc1234-dirty"},
    ]  # fmt: skip
    data = script.page_data(rows, ["planner", "amcl", "fleet"], False, {"cpu": "a test CPU", "cores": 2})
    page = script.render(data)
    assert "| cross-warehouse plan | 6.88 ms | 422 ms (same A* in pure Python) | 61.3x | <= 20 ms |" in page
    assert "| global localization | 9 of 10 seeds | - | - | >= 8 of 10 |" in page
    assert "`abc1234` with uncommitted changes" in page and "a test CPU, 2 cores" in page
    assert "No figures from `fleet`" in page
    assert page.index("## amcl") > page.index("## planner")  # bench/run.py's order
    (tmp_path / "performance.md").write_text(page)
    assert script.main(["--check", "-o", str(tmp_path / "performance.md")]) == 0
    (tmp_path / "performance.md").write_text(page.replace("6.88 ms", "3.00 ms"))
    assert script.main(["--check", "-o", str(tmp_path / "performance.md")]) == 1


# --------------------------------------------------------------------------------- the docs build and its install
def test_make_test_builds_the_docs_and_the_install_has_their_tools() -> None:
    makefile = (ROOT / "Makefile").read_text()
    checks = re.search(r'CHECKS="([^"]*)"', makefile)
    assert checks is not None and "docs" in checks.group(1).split()
    recipe = re.search(r"^docs: .*\n\t(.*)$", makefile, re.M)
    assert recipe is not None and "mkdocs build --strict" in recipe.group(1)
    assert "--quiet" not in recipe.group(1)  # mkdocs --quiet drops the warnings --strict would fail on
    assert '-e ".[all,dev,docs,cluster,foxglove]"' in (ROOT / "tools" / "install.sh").read_text()
    extra = load_tool("pyproject_requirements").extra(ROOT / "pyproject.toml", "docs")
    assert {re.split(r"[\[<>=]", r)[0] for r in extra} >= {"mkdocs", "mkdocs-material", "mkdocstrings"}
    every = load_tool("pyproject_requirements").requirements(ROOT / "pyproject.toml", "all")
    assert set(extra) <= set(every)  # the test install (tools/install.sh) installs them


def test_an_unknown_extra_is_refused_by_name(tmp_path: Path) -> None:
    tool = load_tool("pyproject_requirements")
    pyproject = tmp_path / "pyproject.toml"
    pyproject.write_text(
        '[build-system]\nrequires = ["x"]\n[project]\ndependencies = []\n[project.optional-dependencies]\n'
        'docs = ["mkdocs>=1.6", "mkdocstrings[python]>=0.26"]  # a comment\ndev = [\n  "pytest",\n]\n[tool.x]\n'
    )
    assert tool.extra(pyproject, "docs") == ["mkdocs>=1.6", "mkdocstrings[python]>=0.26"]
    assert tool.extra(pyproject, "dev") == ["pytest"]
    with pytest.raises(ValueError, match="no extra 'doc'"):
        tool.extra(pyproject, "doc")
