"""Loading and validating YAML configuration (worlds, robot and navigation parameters).

Every file we read goes through here so that a mistake is reported with the file, the key and, for a
misspelt key, a "did you mean" suggestion, instead of a KeyError far from the cause.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

__all__ = [
    "ConfigError",
    "load_yaml",
    "check_keys",
    "require",
    "as_float",
    "as_int",
    "as_bool",
    "as_str",
    "as_xy",
    "as_pose2d",
    "as_file",
]


#: libyaml's safe loader when PyYAML has it (its wheels do): the same documents for a fraction of the pure Python
#: one's CPU, which every simulator start and run picture pays
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class ConfigError(ValueError):
    """A configuration file is missing, malformed, or holds a bad value."""

    def __init__(self, source: str | Path | None, key: str | None, problem: str) -> None:
        self.source = str(source) if source is not None else None
        self.key = key
        self.problem = problem
        where = self.source or "<config>"
        if key:
            where += f": '{key}'"
        super().__init__(f"{where}: {problem}")


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping, turning every failure into a ConfigError naming the file."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(path, None, "file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(path, None, f"cannot read file ({exc})") from None
    try:
        data = yaml.load(text, Loader=_SAFE_LOADER)
    except yaml.YAMLError as exc:
        raise ConfigError(path, None, f"not valid YAML ({exc})") from None
    if data is None:
        raise ConfigError(path, None, "file is empty")
    if not isinstance(data, dict):
        raise ConfigError(path, None, f"expected a mapping at the top level, got {type(data).__name__}")
    return data


def _suggest(key: str, allowed: Iterable[str]) -> str:
    close = difflib.get_close_matches(key, list(allowed), n=1, cutoff=0.6)
    return f"; did you mean '{close[0]}'?" if close else ""


def check_keys(
    mapping: Mapping[str, Any],
    allowed: Iterable[str],
    source: str | Path | None,
    prefix: str = "",
    required: Iterable[str] = (),
) -> None:
    """Reject unknown keys (with a suggestion) and missing required keys."""
    allowed = list(allowed)
    for key in mapping:
        if key not in allowed:
            raise ConfigError(
                source,
                f"{prefix}{key}",
                f"unknown key{_suggest(str(key), allowed)} (known keys: {', '.join(sorted(allowed))})",
            )
    for key in required:
        if key not in mapping:
            raise ConfigError(source, f"{prefix}{key}", "required key is missing")


def require(mapping: Mapping[str, Any], key: str, source: str | Path | None, prefix: str = "") -> Any:
    if key not in mapping:
        raise ConfigError(source, f"{prefix}{key}", "required key is missing")
    return mapping[key]


_N = TypeVar("_N", int, float)


def _within(value: _N, source: str | Path | None, key: str, minimum: _N | None, maximum: _N | None) -> _N:
    """`value` if it lies within the bounds given (None: no bound); ConfigError otherwise."""
    if minimum is not None and value < minimum:
        raise ConfigError(source, key, f"must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise ConfigError(source, key, f"must be <= {maximum}, got {value}")
    return value


def as_float(
    value: Any,
    source: str | Path | None,
    key: str,
    *,
    minimum: float | None = None,
    maximum: float | None = None,
) -> float:
    """A finite number (bools are refused: `yes` is not 1.0), optionally within bounds."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(source, key, f"expected a number, got {value!r}")
    result = float(value)
    if not math.isfinite(result):
        raise ConfigError(source, key, f"expected a finite number, got {value!r}")
    return _within(result, source, key, minimum, maximum)


def as_int(
    value: Any, source: str | Path | None, key: str, *, minimum: int | None = None, maximum: int | None = None
) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(source, key, f"expected an integer, got {value!r}")
    return _within(value, source, key, minimum, maximum)


def as_bool(value: Any, source: str | Path | None, key: str) -> bool:
    if not isinstance(value, bool):
        raise ConfigError(source, key, f"expected true or false, got {value!r}")
    return value


def as_str(value: Any, source: str | Path | None, key: str) -> str:
    if not isinstance(value, str) or not value:
        raise ConfigError(source, key, f"expected a non-empty string, got {value!r}")
    return value


def as_file(value: Any, source: Path, key: str, what: str = "file") -> Path:
    """A file named in `source`: `~` expanded, relative to the naming file's folder; ConfigError if it is missing."""
    path = Path(as_str(value, source, key)).expanduser()
    path = path if path.is_absolute() else source.parent / path
    if not path.is_file():
        raise ConfigError(source, key, f"{what} not found: {path}")
    return path


def as_xy(value: Any, source: str | Path | None, key: str) -> tuple[float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(source, key, f"expected [x, y], got {value!r}")
    return (as_float(value[0], source, f"{key}[0]"), as_float(value[1], source, f"{key}[1]"))


def as_pose2d(value: Any, source: str | Path | None, key: str) -> tuple[float, float, float]:
    """[x, y] or [x, y, yaw_degrees] -> (x, y, yaw_radians)."""
    if not isinstance(value, (list, tuple)) or len(value) not in (2, 3):
        raise ConfigError(source, key, f"expected [x, y] or [x, y, heading_degrees], got {value!r}")
    x = as_float(value[0], source, f"{key}[0]")
    y = as_float(value[1], source, f"{key}[1]")
    yaw = math.radians(as_float(value[2], source, f"{key}[2]")) if len(value) == 3 else 0.0
    return (x, y, yaw)
