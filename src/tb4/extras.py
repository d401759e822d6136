"""The optional features and the pip extras that provide them (pyproject.toml's [project.optional-dependencies]).

The navigator, the simulator and `tb4 run` need none of them. A feature whose extra is missing says which extra
to install instead of failing with a bare ImportError deep inside a library.
"""

from __future__ import annotations

import importlib.util

__all__ = ["EXTRAS", "MissingExtraError", "require_extra"]

#: extra -> (what it is for, the modules it installs). Mirrors pyproject.toml.
EXTRAS: dict[str, tuple[str, tuple[str, ...]]] = {
    "llm": ("the OpenAI-compatible model backend of gpt_node", ("openai",)),
    "viewer": ("the web viewer", ("starlette", "uvicorn", "websockets")),
    "render": ("pictures of worlds and runs", ("matplotlib",)),
}


class MissingExtraError(RuntimeError):
    """A feature was asked for whose optional dependencies are not installed; the message says how to add them."""


def require_extra(extra: str) -> None:
    """Return if every module of `extra` is importable; MissingExtraError naming the pip command otherwise."""
    purpose, modules = EXTRAS[extra]
    missing = [m for m in modules if importlib.util.find_spec(m) is None]
    if missing:
        raise MissingExtraError(
            f"{purpose} needs the '{extra}' extra ({', '.join(missing)} not installed): "
            f"pip install 'turtlebot4-navigator[{extra}]' (or [all])"
        )
