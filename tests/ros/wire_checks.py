"""Assertions on Nav2 results that hold in either wire format (Kilted or Jazzy nav2_msgs, tb4.wire)."""

from __future__ import annotations

from typing import Any

from tb4.wire import has_field, set_supported

__all__ = ["says", "error_text", "result_with", "sent_message"]


def says(result: Any, needle: str) -> bool:
    """`needle` is in the result's error_msg. Jazzy's route results (ComputeRoute, ComputeAndTrackRoute) have no
    error_msg on the wire, only the code: there the code, asserted beside this, is all a client can read."""
    return not has_field(result, "error_msg") or needle in result.error_msg


def error_text(result: Any) -> str:
    """The result's error_msg for an assertion's message, or what stands in for it in a format without one."""
    return str(result.error_msg) if has_field(result, "error_msg") else "(no error_msg in this wire format)"


def result_with(action: Any, **fields: Any) -> Any:
    """An action result with the fields the installed format has (a fake server's answer in either format)."""
    result = action.Result()
    set_supported(result, **fields)
    return result


def sent_message(action: Any, text: str) -> str:
    """What a client reads of a server's error_msg `text`: the text, or '' where the format has no error_msg."""
    return text if has_field(action.Result, "error_msg") else ""
