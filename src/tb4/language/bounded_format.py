"""One bounded formatter for every value a program can show: truncated while it is built, never after.

``repr()`` or ``str()`` of a list built from shared references (``A1 = [A0, A0]``, ``A2 = [A1, A1]``, ...) builds
the whole text (exponential in the number of statements) before anyone can cut it. Here the writer stops as soon
as the budget is spent, so formatting costs O(limit) whatever the value, and nested values deeper than
`max_level` show as ``[...]`` (reprlib-style). Objects it does not know show as their type name: no foreign
``__repr__`` is ever called.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["ELLIPSIS", "format_value", "bounded_repr", "bounded_text", "clip"]

ELLIPSIS = "…"
_MAX_LEVEL = 6
_INT_DIGITS = 30  # longer integers print as <int of N bits>: str(int) is quadratic in its length


class _Full(Exception):
    """The budget is spent: stop writing."""


class _Writer:
    def __init__(self, limit: int, max_level: int) -> None:
        self.parts: list[str] = []
        self.left = limit
        self.max_level = max_level

    def put(self, text: str) -> None:
        if len(text) > self.left:
            self.parts.append(text[: max(self.left, 0)])
            self.left = -1
            raise _Full
        self.parts.append(text)
        self.left -= len(text)

    def value(self, value: Any, level: int, top_text: bool = False) -> None:
        if isinstance(value, str):
            if top_text:
                self.put(value[: self.left + 1])
            else:
                self.put(repr(value[: self.left + 1]))
            return
        if value is None or isinstance(value, bool):
            self.put(repr(value))
        elif isinstance(value, int):
            self.put(repr(value) if abs(value) < 10**_INT_DIGITS else f"<int of {value.bit_length()} bits>")
        elif isinstance(value, float):
            self.put(repr(value) if math.isfinite(value) else str(value))
        elif isinstance(value, (list, tuple)):
            self._sequence(value, level)
        elif isinstance(value, dict):
            self._dict(value, level)
        else:
            custom = getattr(type(value), "__bounded_format__", None)
            self.put(custom(value) if custom is not None else f"<{type(value).__name__}>")

    def _sequence(self, value: list[Any] | tuple[Any, ...], level: int) -> None:
        open_, close = ("[", "]") if isinstance(value, list) else ("(", ")")
        if level >= self.max_level and value:
            self.put(f"{open_}...{close}")
            return
        self.put(open_)
        for i, item in enumerate(value):
            if i:
                self.put(", ")
            self.value(item, level + 1)
        if isinstance(value, tuple) and len(value) == 1:
            self.put(",")
        self.put(close)

    def _dict(self, value: dict[Any, Any], level: int) -> None:
        if level >= self.max_level and value:
            self.put("{...}")
            return
        self.put("{")
        for i, (key, item) in enumerate(value.items()):
            if i:
                self.put(", ")
            self.value(key, level + 1)
            self.put(": ")
            self.value(item, level + 1)
        self.put("}")


def format_value(value: Any, limit: int, text: bool = False, max_level: int = _MAX_LEVEL) -> tuple[str, bool]:
    """(text, complete): at most `limit` characters of repr(value) (of str(value) when `text`), and whether that
    is all of it. The work done is proportional to `limit`, not to the size of the value."""
    writer = _Writer(max(limit, 0), max_level)
    try:
        writer.value(value, 0, top_text=text)
    except _Full:
        return "".join(writer.parts)[:limit], False
    return "".join(writer.parts), True


def bounded_repr(value: Any, limit: int = 80) -> str:
    """repr(value) in at most `limit` characters (an ellipsis marks a cut)."""
    out, complete = format_value(value, max(limit - 1, 0))
    return out if complete else out + ELLIPSIS


def bounded_text(value: Any, limit: int = 300) -> str:
    """str(value) in at most `limit` characters (an ellipsis marks a cut)."""
    out, complete = format_value(value, max(limit - 1, 0), text=True)
    return out if complete else out + ELLIPSIS


def clip(text: str, limit: int) -> str:
    """`text` cut to at most `limit` characters, with an ellipsis when cut."""
    return text if len(text) <= limit else text[: max(limit - 1, 0)] + ELLIPSIS
