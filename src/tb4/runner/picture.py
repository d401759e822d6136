"""The picture of a run, drawn from the simulator's run record (a fleet's: every robot in its own colour)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from tb4.sim.render import RobotDrawing, render_world
from tb4.sim.world import World

__all__ = [
    "load_record",
    "render_run",
    "render_record",
    "record_path_of",
    "navigation_goals",
    "navigation_results",
    "robot_parts",
    "bump_events",
]

NAVIGATION_ACTIONS = ("navigate_to_pose", "navigate_through_poses", "follow_waypoints")


def load_record(path: Path) -> dict[str, Any]:
    """A run record (the simulator's run.json) as a dict.

    Raises:
        OSError: the file cannot be read.
        ValueError: it is not a run record (not JSON, or no trajectory and events).
    """
    try:
        record = json.loads(Path(path).read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"{path} is not a run record (not JSON: {exc})") from None
    if not isinstance(record, dict) or not {"trajectory", "events", "world"} <= record.keys():
        raise ValueError(f"{path} is not a run record (it has no trajectory, events and world)")
    return record


def record_path_of(run: Path) -> Path:
    """The run record of a run folder (its run.json), or `run` itself when it is a file.

    Raises:
        ValueError: a folder without a run.json, or a path that does not exist.
    """
    run = Path(run)
    if run.is_dir():
        record = run / "run.json"
        if not record.is_file():
            raise ValueError(f"{run} is not a run folder (no run.json in it)")
        return record
    if not run.exists():
        raise ValueError(f"no such run folder or record: {run}")
    return run


def render_record(run: Path, output: Path | None = None) -> Path:
    """Draw a run folder's or run record's picture on the world it ran in.

    Args:
        run: a run folder (runs/NAME-DATE) or a run record file.
        output: the PNG to write (default: run.png beside the record).

    Returns:
        The PNG written.

    Raises:
        OSError: a file cannot be read or written.
        ValueError: not a run folder or record, or its world cannot be loaded.
    """
    from tb4.sim.world import load_world

    path = record_path_of(run)
    record = load_record(path)
    world_file = record.get("world_file")
    source = world_file if world_file and Path(world_file).is_file() else record["world"]
    world = load_world(source)
    output = output if output is not None else path.with_name("run.png")
    return render_run(world, record, output, title=f"run {path.parent.name} ({world.name})")


def navigation_goals(record: dict[str, Any]) -> list[tuple[float, float, float]]:
    """Every pose sent to a navigation action, in the order they were sent."""
    goals: list[tuple[float, float, float]] = []
    for event in record["events"]:
        if event["type"] == "goal" and event["action"] in NAVIGATION_ACTIONS:
            goals.extend(tuple(p) for p in event["poses"])
    return goals


def navigation_results(record: dict[str, Any]) -> list[str]:
    """The status of every navigation goal that ended, in order ("succeeded", "aborted", ...)."""
    return [e["status"] for e in record["events"] if e["type"] == "result" and e["action"] in NAVIGATION_ACTIONS]


def bump_events(record: dict[str, Any]) -> list[dict[str, Any]]:
    """Every bump of one robot's part of a record, in order: {"t", "x", "y"}."""
    return [e for e in record["events"] if e["type"] == "bump"]


def robot_parts(record: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Every robot's part of a record by namespace: a fleet's `robots`, or the one robot's (the top level)."""
    robots = record.get("robots")
    if robots:
        return dict(robots)
    return {"": record}


def _fleet_drawings(record: dict[str, Any]) -> dict[str, RobotDrawing]:
    drawings = {}
    for namespace, part in robot_parts(record).items():
        ended = navigation_results(part)
        succeeded = ended.count("succeeded")
        drawings[namespace] = RobotDrawing(
            trajectory=np.asarray(part["trajectory"], dtype=float).reshape(-1, 4),
            plans=[np.asarray(p["xy"], dtype=float) for p in part["plans"] if len(p["xy"]) >= 2],
            goals=navigation_goals(part),
            recoveries=[(x, y) for _, x, y in part["recoveries"]],
            label=f"{namespace}: {succeeded}/{len(ended)} goals succeeded",
        )
    return drawings


def render_run(world: World, record: dict[str, Any], output: Path, title: str) -> Path:
    if record.get("robots"):
        return _render_fleet_run(world, record, output, title)
    trajectory = np.asarray(record["trajectory"], dtype=float).reshape(-1, 4)[:, :3]  # (t, x, y): one array op
    plans = [np.asarray(p["xy"], dtype=float) for p in record["plans"] if len(p["xy"]) >= 2]
    last = record["trajectory"][-1] if record["trajectory"] else None
    estimate = np.array([(x, y) for _, x, y, _ in record.get("estimates", [])], dtype=float).reshape(-1, 2)
    error = record.get("localization_error")
    summary = record.get("summary", {})
    if error and summary.get("localization") not in (None, "truth"):
        title += (
            f" — {summary['localization']}: mean error {error['mean_position_error']:.2f} m, "
            f"{error['mean_heading_error_deg']:.1f} deg"
        )
    return render_world(
        world,
        output,
        trajectory=trajectory if len(trajectory) >= 2 else None,
        estimate=estimate if len(estimate) >= 2 and summary.get("localization") != "truth" else None,
        plans=plans,
        goals=navigation_goals(record),
        recoveries=[(x, y) for _, x, y in record["recoveries"]],
        bumps=[(e["x"], e["y"]) for e in bump_events(record)],
        robot_pose=(last[1], last[2], last[3]) if last else None,
        title=title,
        obstacle_time=float(record["summary"].get("sim_time", 0.0)),
    )


def _render_fleet_run(world: World, record: dict[str, Any], output: Path, title: str) -> Path:
    """Every robot's trajectory, plans, goals and last pose in its own colour; the legend counts its results."""
    return render_world(
        world,
        output,
        title=title,
        obstacle_time=float(record["summary"].get("sim_time", 0.0)),
        fleet=_fleet_drawings(record),
    )
