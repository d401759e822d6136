"""Upstream import path: `from nav2_simple_commander.line_iterator import LineIterator`."""

from tb4.navigator.line_iterator import LineIterator

__all__ = ["LineIterator"]
