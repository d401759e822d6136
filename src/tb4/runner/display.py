"""What the user sees during `tb4 run`: a live panel on a terminal, plain lines otherwise, or JSON events."""

from __future__ import annotations

import json
import sys
import time
from typing import Any, TextIO

from rich.console import Console
from rich.live import Live
from rich.table import Table

__all__ = ["Display", "format_status_line"]


def _fmt_time(seconds: float | None) -> str:
    if seconds is None:
        return "-"
    seconds = max(0.0, seconds)
    return f"{int(seconds // 60)}:{seconds % 60:04.1f}" if seconds >= 60 else f"{seconds:.1f} s"


def _dock_text(state: dict[str, Any]) -> str:
    if state.get("docked"):
        return "docked" + (" (charging)" if state.get("charging") else "")
    if state.get("docked") is None:
        return "-"
    return "undocked" + (", dock in view" if state.get("dock_visible") else "")


def format_status_line(state: dict[str, Any], waypoints_total: int | None = None) -> str:
    """One line of progress, used by the plain mode and as the live panel's content."""
    parts = [f"task: {state['task']}"]
    if state.get("distance_remaining") is not None and state["task"].startswith("navigate"):
        parts.append(f"{state['distance_remaining']:.1f} m to go")
    eta = state.get("eta_sim")
    if eta is not None and state["task"].startswith(("navigate", "follow")):
        rtf = state.get("real_time_factor")
        wall = f", {_fmt_time(eta / rtf)} wall" if rtf else ""
        parts.append(f"ETA {_fmt_time(eta)} sim{wall}")
    if state.get("waypoint") is not None:
        total = f"/{waypoints_total}" if waypoints_total else ""
        parts.append(f"waypoint {state['waypoint'] + 1}{total}")
    if state.get("poses_remaining") is not None:
        parts.append(f"{state['poses_remaining']} poses left")
    if state.get("recoveries"):
        parts.append(f"{state['recoveries']} recoveries")
    if state.get("bumps"):
        parts.append(f"BUMPS {state['bumps']}")
    if state.get("localization_error") is not None:
        parts.append(f"localization {100 * state['localization_error']:.0f} cm off")
    if state.get("battery") is not None:
        parts.append(f"battery {100 * state['battery']:.0f}%")
    parts.append(_dock_text(state))
    parts.append(f"sim {_fmt_time(state.get('sim_time'))}")
    if state.get("real_time_factor"):
        parts.append(f"{state['real_time_factor']:.0f}x")
    return " | ".join(parts)


class Display:
    """mode: 'live' (rich panel), 'plain' (a status line every few seconds), 'json', or 'quiet'."""

    def __init__(self, mode: str, waypoints_total: int | None = None, out: TextIO | None = None) -> None:
        self.mode = mode
        self.out = out or sys.stdout
        self.waypoints_total = waypoints_total
        self.console = Console(file=self.out, highlight=False)
        self._live: Live | None = None
        self._last_plain = 0.0
        self._last_line = ""
        self._last_task = ""

    def start(self) -> None:
        if self.mode == "live":
            self._live = Live(
                self._panel({"task": "starting"}), console=self.console, refresh_per_second=8, transient=False
            )
            self._live.start()

    def stop(self) -> None:
        if self._live is not None:
            self._live.stop()
            self._live = None

    def _panel(self, state: dict[str, Any]) -> Table:
        table = Table.grid(padding=(0, 2))
        table.add_column(style="bold cyan")
        table.add_column()
        table.add_row("task", str(state.get("task")))
        if state.get("distance_remaining") is not None:
            table.add_row("distance", f"{state['distance_remaining']:.1f} m remaining")
        if state.get("eta_sim") is not None:
            rtf = state.get("real_time_factor")
            wall = f" ({_fmt_time(state['eta_sim'] / rtf)} wall)" if rtf else ""
            table.add_row("ETA", f"{_fmt_time(state['eta_sim'])} sim{wall}")
        if state.get("waypoint") is not None:
            total = f"/{self.waypoints_total}" if self.waypoints_total else ""
            table.add_row("waypoint", f"{state['waypoint'] + 1}{total}")
        if state.get("poses_remaining") is not None:
            table.add_row("poses left", str(state["poses_remaining"]))
        if state.get("recoveries"):
            table.add_row("recoveries", str(state["recoveries"]))
        if state.get("localization_error") is not None:
            table.add_row(
                "localization",
                f"{100 * state['localization_error']:.0f} cm, "
                f"{state.get('heading_error_deg') or 0.0:.1f}° off the truth",
            )
        battery = state.get("battery")
        table.add_row("battery", "-" if battery is None else f"{100 * battery:.1f}%")
        table.add_row("dock", _dock_text(state))
        rtf = state.get("real_time_factor")
        table.add_row("sim time", f"{_fmt_time(state.get('sim_time'))}" + (f"  ({rtf:.0f}x real time)" if rtf else ""))
        return table

    def update(self, state: dict[str, Any]) -> None:
        if self.mode == "live" and self._live is not None:
            self._live.update(self._panel(state))
        elif self.mode == "plain":
            line = format_status_line(state, self.waypoints_total)
            now = time.monotonic()
            if now - self._last_plain >= 2.0 and line != self._last_line:
                self._last_plain, self._last_line = now, line
                print(f"[tb4 run] {line}", file=self.out, flush=True)
        elif self.mode == "json":
            now = time.monotonic()
            task = str(state.get("task"))
            if now - self._last_plain >= 0.5 or task != self._last_task:  # and at once when the task changes
                self._last_plain, self._last_task = now, task
                self.event({"event": "progress", **{k: v for k, v in state.items() if v is not None}})

    def log(self, line: str) -> None:
        """A line of the tutorial's own output."""
        if self.mode == "json":
            self.event({"event": "log", "line": line})
        elif self.mode == "quiet":
            return
        elif self._live is not None:
            self._live.console.print(line, markup=False, highlight=False)
        else:
            print(line, file=self.out, flush=True)

    def event(self, fields: dict[str, Any]) -> None:
        if self.mode == "json":
            print(json.dumps(fields, default=str), file=self.out, flush=True)
        elif fields.get("event") == "bump":  # news in every mode: a collision the mission itself may never notice
            self.message(f"[tb4 run] bump {fields.get('count')} at sim time {fields.get('sim_time')} s")

    def message(self, text: str) -> None:
        """A message of tb4 run itself (shown in every mode but json, where it is an event)."""
        if self.mode == "json":
            self.event({"event": "message", "text": text})
        elif self.mode == "quiet":
            return
        elif self._live is not None:
            self._live.console.print(text, markup=False, highlight=False)
        else:
            print(text, file=self.out, flush=True)
