"""The model's context: rules, our few-shot examples (a data file), the world's destinations, the user's command.

Code as Policies: the model continues a "# comment / code" listing. The examples use a made-up example world so
the model learns the pattern without being tempted to reuse their names; the real destinations follow.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from functools import lru_cache
from pathlib import Path

from tb4.core.directions import DIRECTIONS
from tb4.language.vocabulary import ALLOWED_METHODS

__all__ = [
    "PROMPT_FILE",
    "EXAMPLE_DESTINATIONS",
    "few_shot_examples",
    "destinations_line",
    "system_message",
    "build_messages",
    "extract_program",
]

PROMPT_FILE = Path(__file__).resolve().parent / "few_shot_prompt.txt"

#: The made-up places the few-shot examples refer to.
EXAMPLE_DESTINATIONS: dict[str, list[float]] = {
    "paint shop": [5.0, -1.0, 90],
    "reception": [-2.0, 4.0, 180],
    "dock": [-1.0, 0.0, 0],
}


@lru_cache(maxsize=4)
def few_shot_examples(path: Path = PROMPT_FILE) -> str:
    """The few-shot listing, read from its data file."""
    return path.read_text(encoding="utf-8").strip() + "\n"


def destinations_line(destinations: Mapping[str, Sequence[float]]) -> str:
    """`destinations = {...}` as the program sees it: name -> [x, y, heading_degrees]."""
    items = ", ".join(f"{name!r}: [{', '.join(f'{float(v):g}' for v in row)}]" for name, row in destinations.items())
    return "destinations = {" + items + "}"


def system_message() -> str:
    methods = ", ".join(f"navigator.{m}" for m in ALLOWED_METHODS)
    directions = ", ".join(f"TurtleBot4Directions.{d} ({v}°)" for d, v in DIRECTIONS.items())
    return (
        "You write short Python programs that control a TurtleBot 4 robot. Reply with code only, no prose and no "
        "markdown. The program must be straight-line code: assignments, literals, lists, list comprehensions over "
        "short lists, destination look-ups destinations[name] (a [x, y, heading_degrees] list) and calls to these "
        f"methods only: {methods}. Headings are degrees: {directions}; north is +x and west is +y on the map. "
        "No imports, no loops, no if, no functions, no other calls. If the request cannot be done with these "
        "methods, call navigator.warn with a short explanation. Use only destinations listed for the real world. "
        "To dock, first go to destinations['dock'] (in front of the charging dock), then call navigator.dock()."
    )


def build_messages(text: str, destinations: Mapping[str, Sequence[float]]) -> list[dict[str, str]]:
    """Chat Completions messages for one command."""
    command = " ".join(str(text).split())
    user = (
        "Examples, in an example world where\n"
        f"{destinations_line(EXAMPLE_DESTINATIONS)}\n\n"
        f"{few_shot_examples()}\n"
        "Now the real world, where\n"
        f"{destinations_line(destinations)}\n\n"
        f"# {command}\n"
    )
    return [{"role": "system", "content": system_message()}, {"role": "user", "content": user}]


_FENCE = re.compile(r"```[a-zA-Z0-9_+-]*\n(.*?)(?:```|\Z)", re.S)


def extract_program(reply: str) -> str:
    """The program in a model's reply: inside a code fence if there is one, up to the next '#' comment block.

    Leading comment lines (an echo of the command) are kept; a comment after code starts a new, unrequested
    command, so it and everything after it is dropped (upstream stops generation at '#' for the same reason).
    """
    text = reply or ""
    fence = _FENCE.search(text)
    if fence:
        text = fence.group(1)
    lines = text.replace("\r\n", "\n").split("\n")
    out: list[str] = []
    seen_code = False
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("#"):
            if seen_code:
                break
        elif stripped:
            seen_code = True
        out.append(line.rstrip())
    return "\n".join(out).strip() + "\n"
