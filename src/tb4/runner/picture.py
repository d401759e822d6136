"""The picture of a run, drawn from the simulator's run record (a fleet's: every robot in its own colour)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from tb4.sim.render import RobotDrawing, render_world
from tb4.sim.world import World

__all__ = ["load_record", "render_run", "navigation_goals", "navigation_results", "robot_parts"]

NAVIGATION_ACTIONS = ("navigate_to_pose", "navigate_through_poses", "follow_waypoints")


def load_record(path: Path) -> dict[str, Any]:
    return json.loads(Path(path).read_text(encoding="utf-8"))


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
