"""What a robotics tester checks after a run, as assertions that read at a glance and fail with where to look.

Every failure message says what was expected, what happened (the nearest miss, its sim time, the bump's place),
and names the run's picture and recording. Positions are the simulator's ground truth, not the robot's estimate.

    record = tb4_mission("my_mission.py")
    assert_succeeded(record)
    assert_visited_in_order(record, ["office", "packing station"], places=Places.of_world("warehouse"))
    assert_no_collision(record)
    assert_clearance(record, at_least=0.05)
    assert_docked_at_end(record)
    assert_finished_within(record, sim_seconds=600)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from tb4.testing.record import RunRecord

__all__ = [
    "REACHED",
    "assert_succeeded",
    "assert_reached",
    "assert_visited_in_order",
    "assert_docked_at_end",
    "assert_no_collision",
    "assert_clearance",
    "assert_finished_within",
    "assert_final_pose",
]

#: how close (m) the true pose must come to a goal: Nav2's xy_goal_tolerance (0.25 m) is checked on the AMCL
#: estimate, which may be some 0.15 m off the truth
REACHED = 0.4


def _fail(record: RunRecord, message: str) -> AssertionError:
    return AssertionError(f"{message} [{record.files}]")


def _point(target: Any, places: Any) -> tuple[str, float, float]:
    """(label, x, y) of a place name, an (x, y[, yaw]) sequence, or a PoseStamped."""
    if isinstance(target, str):
        if places is None:
            raise TypeError(f"a place name ({target!r}) needs places=Places...(...) to look it up")
        x, y, _ = places.xy_yaw(target)
        return (repr(target), x, y)
    if hasattr(target, "pose"):  # geometry_msgs PoseStamped
        position = target.pose.position
        return (f"({position.x:g}, {position.y:g})", float(position.x), float(position.y))
    x, y = float(target[0]), float(target[1])
    return (f"({x:g}, {y:g})", x, y)


def assert_succeeded(record: RunRecord) -> None:
    """The mission ended with exit code 0.

    Args:
        record: the run.

    Raises:
        AssertionError: it did not, with its exit code and reason.
    """
    if not record.succeeded:
        raise _fail(record, f"the mission failed (exit code {record.exit_code}): {record.reason}")


def assert_reached(record: RunRecord, target: Any, tolerance: float = REACHED, places: Any = None) -> float:
    """The robot came within `tolerance` m of `target`.

    Args:
        record: the run.
        target: a place name (with `places`), an (x, y[, yaw]) sequence, or a PoseStamped.
        tolerance: metres, on the true pose.
        places: a tb4.places.Places to look place names up in.

    Returns:
        The sim time of the closest approach.

    Raises:
        AssertionError: never that close; the closest distance and its sim time.
    """
    label, x, y = _point(target, places)
    distance, t = record.closest_approach(x, y)
    if distance > tolerance:
        raise _fail(record, f"never reached {label} within {tolerance:g} m: closest {distance:.2f} m at t={t:.1f} s")
    return t


def assert_visited_in_order(
    record: RunRecord, targets: Sequence[Any], tolerance: float = REACHED, places: Any = None
) -> list[float]:
    """The robot came within `tolerance` m of each target, each after the one before.

    Args:
        record: the run.
        targets: place names (with `places`), (x, y) sequences or PoseStampeds, in the order to visit them.
        tolerance: metres, on the true pose.
        places: a tb4.places.Places to look place names up in.

    Returns:
        The sim time at which each was reached.

    Raises:
        AssertionError: the first target not reached in order, with the closest approach after the one before.
    """
    times: list[float] = []
    after = -math.inf
    for k, target in enumerate(targets):
        label, x, y = _point(target, places)
        distance, t = record.closest_approach(x, y, after=after)
        if distance > tolerance:
            before = f" after {_point(targets[k - 1], places)[0]} (t={after:.1f} s)" if k else ""
            raise _fail(
                record,
                f"target {k + 1} of {len(targets)}, {label}, not reached within {tolerance:g} m{before}: "
                f"closest {distance:.2f} m at t={t:.1f} s",
            )
        times.append(t)
        after = t
    return times


def assert_final_pose(record: RunRecord, target: Any, tolerance: float = REACHED, places: Any = None) -> None:
    """The robot ended within `tolerance` m of `target`.

    Args:
        record: the run.
        target: a place name (with `places`), an (x, y[, yaw]) sequence, or a PoseStamped.
        tolerance: metres, on the true pose.
        places: a tb4.places.Places to look place names up in.

    Raises:
        AssertionError: where it ended instead, and how far that is.
    """
    label, x, y = _point(target, places)
    final = record.final_pose
    if final is None:
        raise _fail(record, "the run has no trajectory")
    distance = math.hypot(final[0] - x, final[1] - y)
    if distance > tolerance:
        raise _fail(record, f"ended at ({final[0]:.2f}, {final[1]:.2f}), {distance:.2f} m from {label}")


def assert_docked_at_end(record: RunRecord) -> None:
    """The robot was on its dock when the run ended.

    Args:
        record: the run.

    Raises:
        AssertionError: it was not, with where it stood.
    """
    if not record.docked_at_end:
        final = record.final_pose
        where = f" at ({final[0]:.2f}, {final[1]:.2f})" if final else ""
        raise _fail(record, f"not docked at the end{where}")


def assert_no_collision(record: RunRecord) -> None:
    """The bumper was never pressed.

    Args:
        record: the run.

    Raises:
        AssertionError: the bumps, each with its place and sim time.
    """
    bumps = record.bumps
    if bumps:
        listed = ", ".join(f"({b['x']:.2f}, {b['y']:.2f}) at t={b['t']:.1f} s" for b in bumps[:5])
        more = f" and {len(bumps) - 5} more" if len(bumps) > 5 else ""
        raise _fail(record, f"{len(bumps)} bump(s): {listed}{more}")


def assert_clearance(record: RunRecord, at_least: float, away_from_dock: float = 0.6) -> float:
    """The robot's body kept at least `at_least` m from every wall and obstacle, away from the docks.

    Args:
        record: the run.
        at_least: metres.
        away_from_dock: samples within this many metres of a dock do not count (docking touches it).

    Returns:
        The smallest clearance (inf when the robot never left the docks).

    Raises:
        AssertionError: closer than that, with where and when.
    """
    closest = record.min_clearance(away_from_dock)
    if closest is None:
        return math.inf
    clearance, t, x, y = closest
    if clearance < at_least:
        raise _fail(record, f"clearance {clearance:.3f} m < {at_least:g} m at ({x:.2f}, {y:.2f}), t={t:.1f} s")
    return clearance


def assert_finished_within(record: RunRecord, sim_seconds: float) -> None:
    """The run took at most `sim_seconds` of sim time.

    Args:
        record: the run.
        sim_seconds: the limit.

    Raises:
        AssertionError: it took longer.
    """
    if record.sim_time > sim_seconds:
        raise _fail(record, f"took {record.sim_time:.1f} s of sim time, more than {sim_seconds:g} s")
