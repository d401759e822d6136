"""What happened during a simulator run, written as JSON when the simulator stops.

The record is taken inside the simulator loop (ground truth, every goal and result the servers handled), so it
is complete and exact however fast the run went; `tb4 run` draws the run's picture from it and the end-to-end
tests check goals, order and docking against it. No rclpy here.

Each robot's part (trajectory, estimates, goals, results, plans, recoveries) is a RobotRecord. The file keeps the
one-robot layout at its top level (the first robot's part), so readers of one-robot records work unchanged; a
fleet's record (RECORD_VERSION 2) adds `robots`: every robot's part by namespace, the first one included.
"""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from tb4.core.geometry import wrap_angle

__all__ = ["RunRecord", "RobotRecord", "RECORD_VERSION", "write_run_section"]

TRAJECTORY_PERIOD = 0.2  # s of sim time between trajectory samples
BATTERY_PERIOD = 1.0  # s of sim time between battery samples (it changes slowly)
MAX_PLANS = 200
RECORD_VERSION = 2  # 2: a fleet's record holds `robots`, every robot's part by namespace


class RobotRecord:
    """One robot's part of the record: the ROS interfaces of that robot write goals, results, notes and plans here."""

    def __init__(self, namespace: str = "") -> None:
        self.namespace = namespace
        self._lock = threading.Lock()
        self.trajectory: list[tuple[float, float, float, float]] = []  # ground truth
        self.estimates: list[tuple[float, float, float, float]] = []  # the localizer's map pose, same times
        self.events: list[dict[str, Any]] = []
        self.plans: list[dict[str, Any]] = []
        self.recoveries: list[tuple[float, float, float]] = []
        self._last_recoveries: dict[int, int] = {}
        self.battery: list[tuple[float, float]] = []  # (t, level 0..1)
        # (t, m): the robot's body to the nearest wall or obstacle, each trajectory sample while it is off the dock
        self.clearance: list[tuple[float, float]] = []

    def sample(self, t: float, x: float, y: float, yaw: float) -> None:
        with self._lock:
            self.trajectory.append((round(t, 3), round(x, 4), round(y, 4), round(yaw, 4)))

    def battery_level(self, t: float, level: float) -> None:
        """The battery's level at sim time t, kept once per BATTERY_PERIOD."""
        with self._lock:
            if not self.battery or t - self.battery[-1][0] >= BATTERY_PERIOD - 1e-9:
                self.battery.append((round(t, 3), round(level, 5)))

    def clearance_sample(self, t: float, clearance: float) -> None:
        """How far the robot's body is from the nearest surface at sim time t (not sampled while docked: the
        dock touches it by design)."""
        with self._lock:
            self.clearance.append((round(t, 3), round(clearance, 4)))

    def estimate(self, t: float, x: float, y: float, yaw: float) -> None:
        """Where localization put the robot at sim time t (beside the truth of `sample`)."""
        with self._lock:
            self.estimates.append((round(t, 3), round(x, 4), round(y, 4), round(yaw, 4)))

    def localization_error(self) -> dict[str, float] | None:
        """Mean and max position error (m) and mean heading error (deg) of the estimate against the truth."""
        with self._lock:
            truth = {t: (x, y, yaw) for t, x, y, yaw in self.trajectory}
            pairs = [(truth[t], (x, y, yaw)) for t, x, y, yaw in self.estimates if t in truth]
        if not pairs:
            return None
        pos = [math.hypot(a[0] - b[0], a[1] - b[1]) for a, b in pairs]
        yaw = [abs(math.degrees(wrap_angle(a[2] - b[2]))) for a, b in pairs]
        return {
            "mean_position_error": round(sum(pos) / len(pos), 4),
            "max_position_error": round(max(pos), 4),
            "mean_heading_error_deg": round(sum(yaw) / len(yaw), 3),
        }

    def goal(self, action: str, t: float, poses: list[tuple[float, float, float]], goal_id: int) -> None:
        with self._lock:
            self.events.append(
                {
                    "type": "goal",
                    "action": action,
                    "t": round(t, 3),
                    "id": goal_id,
                    "poses": [[round(v, 4) for v in p] for p in poses],
                }
            )

    def result(self, action: str, t: float, status: str, goal_id: int, error_code: int, error_msg: str) -> None:
        with self._lock:
            self.events.append(
                {
                    "type": "result",
                    "action": action,
                    "t": round(t, 3),
                    "id": goal_id,
                    "status": status,
                    "error_code": int(error_code),
                    "error_msg": error_msg,
                }
            )

    def note(self, kind: str, t: float, **data: Any) -> None:
        """Something a person or a script did to the robot (light ring, audio, button, kidnap, e-stop...)."""
        with self._lock:
            if len(self.events) < 100_000:
                self.events.append({"type": kind, "t": round(t, 3), **data})

    def plan(self, t: float, path: Any) -> None:
        with self._lock:
            if len(self.plans) >= MAX_PLANS:
                return
            step = max(1, len(path) // 400)
            # rounded as an array: a plan comes with each replanning, and rounding it pose by pose in Python took a
            # visible share of a simulator's time at --rate max
            xy = np.round(np.asarray(path, dtype=np.float64)[::step, :2], 3).tolist()
            self.plans.append({"t": round(t, 3), "xy": xy})

    def task_progress(self, task: Any, t: float, x: float, y: float) -> None:
        """Notes where recoveries happened: when a task's number_of_recoveries goes up."""
        count = getattr(task, "number_of_recoveries", None)
        if not isinstance(count, int):
            return
        previous = self._last_recoveries.get(id(task), 0)
        if count > previous:
            with self._lock:
                self.recoveries.append((round(t, 3), round(x, 3), round(y, 3)))
        self._last_recoveries = {id(task): count}

    def robot_dict(self) -> dict[str, Any]:
        """This robot's part of the file."""
        error = self.localization_error()  # takes the lock itself
        with self._lock:
            return {
                "trajectory": list(self.trajectory),
                "estimates": list(self.estimates),
                "localization_error": error,
                "events": list(self.events),
                "plans": list(self.plans),
                "recoveries": list(self.recoveries),
                "battery": list(self.battery),
                "clearance": list(self.clearance),
            }


class RunRecord(RobotRecord):
    """The whole run: the first robot's part (as in every one-robot record) and, for a fleet, every robot's.

    `fleet`: the namespaces a fleet serves, the first one being this record's own robot; empty for one robot.
    """

    def __init__(self, world: str, path: Path, fleet: tuple[str, ...] = (), world_file: Path | None = None) -> None:
        super().__init__(fleet[0] if fleet else "")
        self.path = path
        self.world = world
        self.world_file = world_file  # where the world was loaded from: `tb4 render` draws any world's run
        self.docks: list[tuple[float, float, float]] = []  # the docked poses: clearance near a dock is by design
        self.robots: dict[str, RobotRecord] = {ns: self if k == 0 else RobotRecord(ns) for k, ns in enumerate(fleet)}
        # the input journal beside the record (file name, inputs, ticks, digest, what replay cannot redo)
        self.replay: dict[str, Any] | None = None

    def restart(self, path: Path | None = None) -> None:
        """Empty every robot's part for a new run (a world reset), to be written to `path` (default: the same).
        The parts stay the same objects: the interfaces that write into them keep writing.

        Args:
            path: where the new run's record goes.
        """
        for part in {id(r): r for r in (self, *self.robots.values())}.values():
            RobotRecord.__init__(part, part.namespace)
        if path is not None:
            self.path = path

    def robot(self, namespace: str) -> RobotRecord:
        """The part of the robot serving under `namespace` (this record itself for a one-robot run)."""
        if not self.robots:
            return self
        return self.robots[namespace]

    def to_dict(self, summary: dict[str, Any]) -> dict[str, Any]:
        own = self.robot_dict()
        data: dict[str, Any] = {"version": RECORD_VERSION, "world": self.world, "summary": summary, **own}
        if self.world_file is not None:
            data["world_file"] = str(self.world_file)
        data["docks"] = [[round(v, 4) for v in dock] for dock in self.docks]
        if self.replay is not None:
            data["replay"] = self.replay
        if self.robots:
            data["robots"] = {ns: own if r is self else r.robot_dict() for ns, r in self.robots.items()}
        return data

    def write(self, summary: dict[str, Any]) -> Path:
        data = self.to_dict(summary)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        tmp.write_text(json.dumps(data, allow_nan=False, default=_finite), encoding="utf-8")
        tmp.replace(self.path)
        return self.path


def _finite(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return str(value)


def write_run_section(path: Path, run: dict[str, Any], summary: dict[str, Any] | None = None) -> dict[str, Any]:
    """Set a written record's `run` section (how the run was started and how it ended: what `tb4 run` and the test
    kit add to the simulator's record) and merge `summary` into its summary; written back whole or not at all.

    Args:
        path: the run record (run.json).
        run: the section: mission, arguments, settings, exit code, reason, wall time, bumps.
        summary: items to add to the record's summary.

    Returns:
        The record as written.

    Raises:
        OSError: it cannot be read or written.
        ValueError: it is not JSON.
    """
    record = json.loads(path.read_text(encoding="utf-8"))
    record["run"] = run
    if summary and isinstance(record.get("summary"), dict):
        record["summary"].update(summary)
    temporary = path.with_suffix(path.suffix + ".tmp")
    temporary.write_text(json.dumps(record, allow_nan=False, default=_finite), encoding="utf-8")
    temporary.replace(path)
    return record
