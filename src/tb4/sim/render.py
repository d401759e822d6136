"""PNG pictures of a world and of a run in it: map, obstacles, dock, destinations, goals, plans, trajectory.

A picture is the quickest way to see what a navigation run did (where it planned, where it drove, where it had
to recover), so tests and the CLI can leave one behind. Uses matplotlib's Agg canvas directly: no display, no
pyplot global state, safe to call from any thread.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon

from tb4.core.robot_params import robot_radius
from tb4.sim.obstacles import Obstacle
from tb4.sim.world import World

__all__ = ["render_world", "RobotDrawing", "DOCK_BODY", "FLEET_COLORS"]

DOCK_BODY = (0.19, 0.39, 0.40)  # station body in the docked robot's frame: x from, x to, width
_LONGEST_SIDE_IN = 10.0
_DPI = 100
_MARGINS_IN = (0.65, 0.45, 0.15, 0.3)  # left, bottom, right, top: tick and axis labels, the title
_COLORBAR_LABELS_IN = 0.75  # more on the right for the colorbar's tick labels and its label
FLEET_COLORS = (
    "#e53935",
    "#1e88e5",
    "#43a047",
    "#8e24aa",
    "#fb8c00",
    "#00897b",
    "#6d4c41",
    "#d81b60",
)  # one per robot


@dataclass(frozen=True)
class RobotDrawing:
    """One fleet robot's run, drawn in its own colour: trajectory (N, >=3) rows of (t, x, y[, yaw]), the plans it
    followed ((N, >=2) x, y), its goals ((x, y, yaw), numbered in order), where it recovered ((x, y)), its last
    pose and its legend label."""

    trajectory: Any
    plans: Sequence[Any] = ()
    goals: Sequence[Sequence[float]] = ()
    recoveries: Sequence[Sequence[float]] = ()
    label: str = ""


# Grid value classes -> colours: unknown, free, occupied.
_MAP_CMAP = ListedColormap(["#b4b4b4", "#ffffff", "#2b2b2b"])


def _map_classes(world: World) -> np.ndarray:
    data = world.map.data
    classes = np.ones(data.shape, dtype=np.uint8)
    classes[data < 0] = 0
    classes[data >= 65] = 2
    return classes


def _obstacle_patch(obs: Obstacle, t: float, **style: Any) -> Circle | Polygon:
    cx, cy = obs.position_at(t)
    if obs.shape == "circle":
        return Circle((cx, cy), obs.radius, **style)
    length, width = obs.size
    c, s = math.cos(obs.yaw), math.sin(obs.yaw)
    corners = np.array([[length, width], [-length, width], [-length, -width], [length, -width]]) / 2
    rot = np.array([[c, -s], [s, c]])
    return Polygon(corners @ rot.T + [cx, cy], closed=True, **style)


def _pose_arrow(ax: Any, x: float, y: float, yaw: float, length: float, color: str, width: float = 0.06) -> None:
    ax.arrow(
        x,
        y,
        length * math.cos(yaw),
        length * math.sin(yaw),
        width=width,
        head_width=width * 3.5,
        head_length=width * 3.5,
        length_includes_head=True,
        color=color,
        zorder=6,
    )


def _draw_fleet_robot(ax: Any, robot: RobotDrawing, color: str, label: str) -> None:
    """A fleet robot's plans (thin), trajectory, numbered goals and last pose, all in `color`."""
    for plan in robot.plans:
        pts = _as_points(plan, 2)
        ax.plot(pts[:, 0], pts[:, 1], lw=0.9, color=color, alpha=0.45, zorder=4)
    pts = _as_points(robot.trajectory, 3) if len(robot.trajectory) else np.zeros((0, 3))
    if len(pts):
        ax.plot(pts[:, 1], pts[:, 2], lw=1.4, color=color, alpha=0.85, zorder=5, label=label)
    for i, goal in enumerate(robot.goals, start=1):
        g = list(goal) + [0.0] * (3 - len(goal))
        _pose_arrow(ax, g[0], g[1], g[2], 0.6, color, width=0.05)
        ax.annotate(
            str(i), (g[0], g[1]), xytext=(-9, 5), textcoords="offset points", fontsize=7, weight="bold", color=color
        )
    if len(robot.recoveries):
        rec = _as_points(robot.recoveries, 2)
        ax.plot(rec[:, 0], rec[:, 1], ls="none", marker="x", ms=7, mew=1.8, color=color, zorder=8)
    if len(pts):
        x, y = pts[-1, 1], pts[-1, 2]
        ax.add_patch(Circle((x, y), robot_radius(), facecolor=color, edgecolor="black", lw=0.8, alpha=0.9, zorder=9))
        if pts.shape[1] >= 4:  # (t, x, y, yaw): show the heading too
            _pose_arrow(ax, x, y, pts[-1, 3], 0.35, "#ffeb3b", width=0.04)


def _drawn_segments(segments: np.ndarray) -> np.ndarray:
    """Which (N, 2, 2) segments to draw: a segment where the robot stood still draws nothing (butt caps), but each
    costs a Path, and hours on the dock are tens of thousands of them. The colour scale stays the whole run's."""
    return np.any(segments[:, 0] != segments[:, 1], axis=1)


def _as_points(seq: Any, min_cols: int) -> np.ndarray:
    arr = np.asarray(seq, dtype=np.float64)
    if arr.ndim == 1 and arr.size >= min_cols:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] < min_cols:
        raise ValueError(f"expected an (N, >={min_cols}) array of points, got shape {arr.shape}")
    return arr


def _draw_route_graph(ax: Any, graph: Any) -> None:
    """Edges as thin teal lines, nodes as dots labelled with their ids (what route goals refer to)."""
    segments = [((x0, y0), (x1, y1)) for x0, y0, x1, y1 in graph.segments()]
    ax.add_collection(LineCollection(segments, colors="#26a69a", linewidths=0.9, alpha=0.8, zorder=1.5))
    for node in graph.nodes.values():
        ax.plot([node.x], [node.y], marker="o", ms=2.5, color="#00796b", zorder=1.6)
        ax.annotate(
            str(node.id),
            (node.x, node.y),
            xytext=(2, 2),
            textcoords="offset points",
            fontsize=4.5,
            color="#004d40",
            zorder=1.7,
        )


def render_world(
    world: World,
    path: str | Path,
    *,
    trajectory: np.ndarray | Sequence[Sequence[float]] | None = None,
    estimate: np.ndarray | Sequence[Sequence[float]] | None = None,
    plans: Sequence[np.ndarray | Sequence[Sequence[float]]] = (),
    goals: Sequence[Sequence[float]] = (),
    recoveries: Sequence[Sequence[float]] = (),
    bumps: Sequence[Sequence[float]] = (),
    robot_pose: Sequence[float] | None = None,
    title: str | None = None,
    obstacle_time: float = 0.0,
    route_graph: Any = None,
    fleet: dict[str, RobotDrawing] | None = None,
) -> Path:
    """Write a PNG of `world` (and optionally a run in it) to `path`; returns the path.

    trajectory: (N, 3) rows of (t, x, y), coloured by time (the ground truth). estimate: (N, >=2) x, y where
    localization put the robot, drawn dashed beside the truth. plans: paths as (N, >=2) arrays of x, y.
    goals: (x, y, yaw) poses, drawn as numbered arrows. recoveries: (x, y) points where a recovery ran.
    bumps: (x, y) points where the bumper was pressed, drawn as red stars with a legend entry.
    robot_pose: (x, y, yaw) of the robot. obstacle_time: sim time at which moving obstacles are drawn.
    route_graph: a tb4.nav.route_graph.RouteGraph (anything with `segments()` and `nodes`), drawn under the rest.
    fleet: every robot's run by namespace (RobotDrawing), one colour each, with a legend.
    """
    out = Path(path)
    grid = world.map
    x0, y0, x1, y1 = grid.bounds
    span_x, span_y = x1 - x0, y1 - y0
    scale = _LONGEST_SIDE_IN / max(span_x, span_y)
    colorbar = trajectory is not None and len(trajectory) >= 2
    fig_w = max(span_x * scale + (1.8 if colorbar else 0.8), 5.0)  # room for the axis labels and the colorbar
    fig_h = max(span_y * scale + 0.6, 4.0)
    fig = Figure(figsize=(fig_w, fig_h), dpi=_DPI)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.imshow(
        _map_classes(world),
        cmap=_MAP_CMAP,
        vmin=0,
        vmax=2,
        origin="lower",
        extent=(x0, x1, y0, y1),
        interpolation="nearest",
        zorder=0,
    )

    for obs in world.static_obstacles:
        ax.add_patch(_obstacle_patch(obs, 0.0, facecolor="#c8782a", edgecolor="#6b3a10", lw=0.8, zorder=3))
    for obs in world.moving_obstacles:
        pts = obs.track()
        ax.plot(pts[:, 0], pts[:, 1], ls="--", lw=1.0, color="#8a2be2", zorder=2)
        ax.add_patch(_obstacle_patch(obs, obstacle_time, facecolor="#b57edc", edgecolor="#5a1a8a", lw=0.8, zorder=3))

    # Dock: the station body just ahead of the docked robot, and the docked pose outline.
    dx, dy, dyaw = world.dock
    c, s = math.cos(dyaw), math.sin(dyaw)
    body = np.array(
        [
            [DOCK_BODY[0], -DOCK_BODY[2] / 2],
            [DOCK_BODY[1], -DOCK_BODY[2] / 2],
            [DOCK_BODY[1], DOCK_BODY[2] / 2],
            [DOCK_BODY[0], DOCK_BODY[2] / 2],
        ]
    )
    body = body @ np.array([[c, -s], [s, c]]).T + [dx, dy]
    ax.add_patch(Polygon(body, closed=True, facecolor="#1f9e3a", edgecolor="#0b4d1a", lw=1.0, zorder=4))
    ax.add_patch(Circle((dx, dy), robot_radius(), fill=False, ls=":", edgecolor="#1f9e3a", lw=1.0, zorder=4))
    ax.annotate("dock", (dx, dy), xytext=(4, -12), textcoords="offset points", fontsize=7, color="#0b4d1a", zorder=7)

    if route_graph is not None:
        _draw_route_graph(ax, route_graph)

    for dest in world.destinations.values():
        ax.plot([dest.x], [dest.y], marker="o", ms=4, color="#1565c0", zorder=5)
        _pose_arrow(ax, dest.x, dest.y, dest.yaw, 0.45, "#1565c0", width=0.03)
        ax.annotate(
            dest.name,
            (dest.x, dest.y),
            xytext=(5, 4),
            textcoords="offset points",
            fontsize=7,
            color="#0d47a1",
            zorder=7,
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
        )

    for plan in plans:
        pts = _as_points(plan, 2)
        ax.plot(pts[:, 0], pts[:, 1], lw=1.2, color="#ff9800", alpha=0.9, zorder=4)

    if trajectory is not None:
        traj = _as_points(trajectory, 3)
        if len(traj) >= 2:
            segments = np.stack([traj[:-1, 1:3], traj[1:, 1:3]], axis=1)
            times = 0.5 * (traj[:-1, 0] + traj[1:, 0])
            moved = _drawn_segments(segments)
            lines = LineCollection(list(segments[moved]), cmap="viridis", linewidths=2.0, zorder=5)
            lines.set_array(times[moved])
            lines.set_clim(float(times.min()), float(times.max()))
            ax.add_collection(lines)
            cbar = fig.colorbar(lines, ax=ax, fraction=0.04, pad=0.02)
            cbar.set_label("sim time [s]")
        elif len(traj) == 1:
            ax.plot(traj[:, 1], traj[:, 2], marker=".", color="#440154", zorder=5)

    for k, (namespace, robot) in enumerate((fleet or {}).items()):
        _draw_fleet_robot(ax, robot, FLEET_COLORS[k % len(FLEET_COLORS)], robot.label or namespace)
    if fleet:
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)

    if estimate is not None and len(estimate) >= 2:
        est = _as_points(estimate, 2)
        ax.plot(est[:, 0], est[:, 1], ls="--", lw=1.0, color="#e53935", zorder=6, label="localization estimate")
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)

    for i, goal in enumerate(goals, start=1):
        g = list(goal) + [0.0] * (3 - len(goal))
        _pose_arrow(ax, g[0], g[1], g[2], 0.7, "#d81b60")
        ax.annotate(
            str(i), (g[0], g[1]), xytext=(-9, 5), textcoords="offset points", fontsize=8, weight="bold", color="#880e4f"
        )

    if len(recoveries):
        rec = _as_points(recoveries, 2)
        ax.plot(rec[:, 0], rec[:, 1], ls="none", marker="x", ms=8, mew=2.0, color="#e53935", zorder=8)

    if len(bumps):
        hits = _as_points(bumps, 2)
        ax.plot(
            hits[:, 0],
            hits[:, 1],
            ls="none",
            marker="*",
            ms=14,
            mew=0.8,
            mfc="#ff1744",
            mec="black",
            zorder=10,
            label=f"bump ({len(hits)})",
        )
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)  # with the estimate's entry, if any

    if robot_pose is not None:
        rx, ry, ryaw = (float(v) for v in robot_pose[:3])
        ax.add_patch(Circle((rx, ry), robot_radius(), facecolor="#37474f", edgecolor="black", lw=0.8, zorder=9))
        _pose_arrow(ax, rx, ry, ryaw, 0.35, "#ffeb3b", width=0.04)

    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.tick_params(labelsize=7)
    ax.grid(True, lw=0.3, alpha=0.4)
    ax.set_title(title if title is not None else f"world: {world.name}", fontsize=10)
    # fixed margins for the tick labels, axis labels and title: tight_layout would draw the whole figure once more
    # only to measure them (a third of a run picture's time)
    fig.subplots_adjust(
        left=_MARGINS_IN[0] / fig_w,
        bottom=_MARGINS_IN[1] / fig_h,
        right=1.0 - (_MARGINS_IN[2] + (_COLORBAR_LABELS_IN if colorbar else 0.0)) / fig_w,
        top=1.0 - _MARGINS_IN[3] / fig_h,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=_DPI)
    return out
