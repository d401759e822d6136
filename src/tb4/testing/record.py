"""A finished run as a test reads it: the simulator's run record (run.json) with what `tb4 run` added, as
properties, with the run's picture and recording beside it.

The record is taken inside the simulator's loop (ground truth every 0.2 s of sim time, every goal and result the
servers handled, every bump), so it is exact however fast the run went. No rclpy here.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RunRecord", "NAVIGATION_ACTIONS"]

NAVIGATION_ACTIONS = ("navigate_to_pose", "navigate_through_poses", "follow_waypoints")


@dataclass
class RunRecord:
    """One run: trajectory, goals and results, bumps, clearance, battery, times, localization error, files.

    Attributes:
        path: the run record file (run.json).
        data: the whole record as loaded (one robot's part at the top level; a fleet's in `robots`).
        exit_code: the mission's exit code (None when the record says nothing of how the mission ended).
        reason: why it ended, in words ("succeeded", "timed out: ...", the exception a script raised).
        picture: the run's picture (run.png), if drawn.
        mcap: the run's MCAP recording, if one was made.
        robot: whose part the properties read: "" for a one-robot run, a fleet robot's namespace otherwise.
    """

    path: Path
    data: dict[str, Any]
    exit_code: int | None = None
    reason: str = ""
    picture: Path | None = None
    mcap: Path | None = None
    robot: str = ""
    _part: dict[str, Any] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        robots = self.data.get("robots") or {}
        if self.robot and self.robot not in robots:
            raise KeyError(f"no robot {self.robot!r} in {self.path} (robots: {sorted(robots) or 'one, unnamed'})")
        self._part = robots[self.robot] if self.robot else self.data
        run = self.data.get("run", {})
        if self.exit_code is None and "exit_code" in run:
            self.exit_code = int(run["exit_code"])
        if not self.reason:
            self.reason = str(run.get("reason", ""))
        if self.picture is None and (self.path.parent / "run.png").is_file():
            self.picture = self.path.parent / "run.png"

    @classmethod
    def load(cls, path: str | Path, **known: Any) -> RunRecord:
        """A record from a run folder or its run.json.

        Raises:
            FileNotFoundError: no such record.
            ValueError: the file is not a run record.
        """
        path = Path(path)
        if path.is_dir():
            path = path / "run.json"
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path} is not a run record: {exc}") from None
        if not isinstance(data, dict) or "trajectory" not in data:
            raise ValueError(f"{path} is not a run record (no trajectory)")
        return cls(path, data, **known)

    def of_robot(self, namespace: str) -> RunRecord:
        """The same run, read as one fleet robot's.

        Args:
            namespace: the robot's namespace ("/robot2").

        Returns:
            A RunRecord whose properties read that robot's part.

        Raises:
            KeyError: no such robot in the run.
        """
        return RunRecord(self.path, self.data, self.exit_code, self.reason, self.picture, self.mcap, namespace)

    # ---------------------------------------------------------------------------------------------- outcome
    @property
    def succeeded(self) -> bool:
        """The mission exited with 0 (a callable trial: returned without raising)."""
        return self.exit_code == 0

    @property
    def run_dir(self) -> Path:
        return self.path.parent

    @property
    def files(self) -> str:
        """Where to look: the picture, the recording and the replay command, for a failure message."""
        parts = [f"picture {self.picture}" if self.picture else f"record {self.path}"]
        if self.mcap is not None:
            parts.append(f"recording {self.mcap}")
        replay_command = self.replay_command
        if replay_command:
            parts.append(f"replay: {replay_command}")
        return "; ".join(parts)

    @property
    def replay_command(self) -> str | None:
        """The `tb4 replay` command that re-runs this run exactly (None: the run kept no input journal)."""
        import shlex

        info = self.data.get("replay")
        if not isinstance(info, dict) or not (self.run_dir / str(info.get("journal", ""))).is_file():
            return None
        return shlex.join(["tb4", "replay", str(self.path)])

    def replay(self) -> Any:
        """Re-run this run from its input journal, in this process and without DDS (`tb4 replay`).

        Returns:
            tb4.replay.engine.ReplayReport: `identical` says whether every robot's pose after every tick is the
            recording's, to the bit.

        Raises:
            tb4.replay.engine.ReplayError: the run kept no journal, or it cannot be replayed.
        """
        from tb4.replay.engine import replay

        return replay(self.path)

    @property
    def sim_time(self) -> float:
        """Sim seconds the run took (the simulator's clock when it stopped)."""
        return float(self.data.get("summary", {}).get("sim_time", 0.0))

    @property
    def wall_time(self) -> float | None:
        """Wall seconds from the mission's start to its end (None when not run by tb4 run)."""
        value = self.data.get("run", {}).get("wall_time")
        return None if value is None else float(value)

    @property
    def seed(self) -> int | None:
        return self.data.get("summary", {}).get("seed")

    # ---------------------------------------------------------------------------------------------- motion
    @property
    def trajectory(self) -> np.ndarray:
        """(N, 4) rows of (t, x, y, yaw): the true pose every 0.2 s of sim time."""
        return np.asarray(self._part["trajectory"], dtype=float).reshape(-1, 4)

    @property
    def final_pose(self) -> tuple[float, float, float] | None:
        """(x, y, yaw) where the robot was at the end."""
        rows = self._part["trajectory"]
        return (rows[-1][1], rows[-1][2], rows[-1][3]) if rows else None

    @property
    def docked_at_end(self) -> bool:
        summary = self.data.get("summary", {})
        if self.robot:
            return bool(summary.get("fleet", {}).get(self.robot, {}).get("docked"))
        return bool(summary.get("docked"))

    def closest_approach(self, x: float, y: float, after: float = -math.inf) -> tuple[float, float]:
        """The robot's nearest true position to a point.

        Args:
            x: the point's x (m, map frame).
            y: the point's y.
            after: only from this sim time on.

        Returns:
            (distance in m, its sim time); (inf, nan) when no sample is that late.
        """
        rows = self.trajectory
        rows = rows[rows[:, 0] >= after]
        if not len(rows):
            return (math.inf, math.nan)
        distances = np.hypot(rows[:, 1] - x, rows[:, 2] - y)
        k = int(np.argmin(distances))
        return (float(distances[k]), float(rows[k, 0]))

    # ---------------------------------------------------------------------------------------------- events
    def events(self, kind: str | None = None) -> list[dict[str, Any]]:
        """The record's events in order.

        Args:
            kind: only this type ("goal", "result", "bump", ...); None for all.

        Returns:
            The events, each a dict with its "type" and sim time "t".
        """
        return [e for e in self._part["events"] if kind is None or e["type"] == kind]

    @property
    def goals(self) -> list[dict[str, Any]]:
        """Every goal the servers accepted: {"action", "t", "id", "poses"}."""
        return self.events("goal")

    @property
    def results(self) -> list[dict[str, Any]]:
        """Every goal's end: {"action", "t", "id", "status", "error_code", "error_msg"}."""
        return self.events("result")

    def navigation_results(self) -> list[str]:
        """Statuses of the navigation goals that ended ("succeeded", "aborted", "canceled"), in order."""
        return [e["status"] for e in self.results if e["action"] in NAVIGATION_ACTIONS]

    @property
    def bumps(self) -> list[dict[str, Any]]:
        """Every bumper press: {"t", "x", "y"}."""
        return self.events("bump")

    # ---------------------------------------------------------------------------------------------- margins
    def min_clearance(self, away_from_dock: float = 0.6) -> tuple[float, float, float, float] | None:
        """The closest the robot's body came to a wall or obstacle.

        Args:
            away_from_dock: leave out samples within this many metres of a dock (docking touches it by design).

        Returns:
            (clearance m, sim time, x, y), or None when the robot never left the docks.
        """
        samples = np.asarray(self._part.get("clearance", []), dtype=float).reshape(-1, 2)
        if not len(samples):
            return None
        rows = self.trajectory
        index = np.clip(np.searchsorted(rows[:, 0], samples[:, 0]), 0, len(rows) - 1)
        xy = rows[index, 1:3]
        keep = np.ones(len(samples), dtype=bool)
        for dock in self.data.get("docks", []):
            keep &= np.hypot(xy[:, 0] - dock[0], xy[:, 1] - dock[1]) > away_from_dock
        if not keep.any():
            return None
        k = int(np.argmin(np.where(keep, samples[:, 1], np.inf)))
        return (float(samples[k, 1]), float(samples[k, 0]), float(xy[k, 0]), float(xy[k, 1]))

    @property
    def battery(self) -> np.ndarray:
        """(N, 2) rows of (t, level 0..1): the battery once per sim second."""
        return np.asarray(self._part.get("battery", []), dtype=float).reshape(-1, 2)

    @property
    def localization_error(self) -> dict[str, float] | None:
        """{"mean_position_error", "max_position_error", "mean_heading_error_deg"} of the estimate vs the truth."""
        return self._part.get("localization_error")
