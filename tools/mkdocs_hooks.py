"""MkDocs hooks of the documentation site (mkdocs.yml `hooks:`): the CLI reference page, written from the `tb4`
command's own argparse parsers (tb4.cli.main.build_parser) at every build, so it always says what the installed
command does and is never committed.

    python tools/mkdocs_hooks.py        # print the page the site holds as reference/cli.md
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from collections.abc import Iterator
from typing import Any

__all__ = ["CLI_PAGE", "cli_reference", "subcommands", "on_files"]

#: where the generated page lives in the site (mkdocs.yml's nav names it)
CLI_PAGE = "reference/cli.md"
_USAGE_WIDTH = 100  # columns of the usage lines (argparse wraps to the terminal's width otherwise)

_INTRO = """\
# CLI reference

Every sub-command of `tb4`, its arguments and options, as `tb4 COMMAND --help` prints them. This page is written
from the command's own parsers each time the site is built, so it cannot drift from the installed command.

Every `tb4` command keeps DDS on this machine (`ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`) unless you set the
variable yourself: see [the real robot](../guides/real-robot.md).
"""


def subcommands(parser: argparse.ArgumentParser) -> Iterator[tuple[str, str, argparse.ArgumentParser]]:
    """(name, one-line help, parser) of each sub-command, in the order `tb4 --help` lists them."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            for name, sub in action.choices.items():
                yield name, helps.get(name, ""), sub


def _text(value: str) -> str:
    """Help text as Markdown: no HTML, no emphasis from a stray star."""
    return value.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("*", "\\*")


def _argument(action: argparse.Action, parser: argparse.ArgumentParser) -> str:
    formatter = parser._get_formatter()
    if action.option_strings:
        takes = (
            ""
            if action.nargs == 0
            else " " + formatter._format_args(action, formatter._get_default_metavar_for_optional(action))
        )
        names = ", ".join(f"`{option}{takes}`" for option in action.option_strings)
    else:
        names = f"`{formatter._format_args(action, formatter._get_default_metavar_for_positional(action))}`"
    words = _text(formatter._expand_help(action)) if action.help else ""
    extras = []
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        extras.append("one of " + ", ".join(f"`{choice}`" for choice in action.choices))
    shown_default = action.default not in (None, False, "", argparse.SUPPRESS) and action.nargs != 0
    if shown_default and action.option_strings and "default" not in words:
        extras.append(f"default `{action.default}`")
    said = "; ".join(extras)
    if words and said:
        return f"- {names}: {words} ({said})"
    return f"- {names}: {words or said}" if words or said else f"- {names}"


def _command(name: str, summary: str, sub: argparse.ArgumentParser) -> list[str]:
    usage = re.sub(r"\s+\n", "\n", sub.format_usage().strip())
    lines = [f"## tb4 {name}", ""]
    if summary:
        lines += [_text(summary[0].upper() + summary[1:]) + ".", ""]
    if sub.description:
        description = " ".join(sub.description.split())
        if "%(prog)" in description:  # as argparse formats it
            description = description % {"prog": sub.prog}
        lines += [_text(description), ""]
    lines += ["```text", usage, "```", ""]
    positionals = [a for a in sub._actions if not a.option_strings and a.help is not argparse.SUPPRESS]
    options = [
        a
        for a in sub._actions
        if a.option_strings and a.help is not argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)
    ]
    if positionals:
        lines += ["**Arguments**", "", *(_argument(a, sub) for a in positionals), ""]
    if options:
        lines += ["**Options**", "", *(_argument(a, sub) for a in options), ""]
    return lines


def cli_reference(parser: argparse.ArgumentParser | None = None) -> str:
    """The CLI reference page (Markdown) of `parser`, by default the `tb4` command's."""
    if parser is None:
        from tb4.cli.main import build_parser

        parser = build_parser()
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(_USAGE_WIDTH)  # argparse sizes its usage lines from it
    try:
        commands = list(subcommands(parser))
        lines = [_INTRO, "| Command | What it does |", "|---|---|"]
        lines += [f"| [`tb4 {name}`](#tb4-{name}) | {_text(summary)} |" for name, summary, _ in commands]
        lines.append("")
        for name, summary, sub in commands:
            lines += _command(name, summary, sub)
    finally:
        if columns is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = columns
    return "\n".join(lines).rstrip() + "\n"


def on_files(files: Any, config: Any) -> Any:
    """MkDocs hook: add the generated CLI reference page to the site's files."""
    from mkdocs.structure.files import File

    files.append(File.generated(config, CLI_PAGE, content=cli_reference()))
    return files


if __name__ == "__main__":
    sys.stdout.write(cli_reference())
