"""The test kit for TurtleBot 4 missions: a simulator of a test's own, trials that return a run record, and
assertions a robotics tester reads at a glance. The pytest plugin (tb4.testing.plugin) wraps them as fixtures.

Importing it starts nothing and imports no ROS module.
"""

from tb4.testing.assertions import (
    REACHED,
    assert_clearance,
    assert_docked_at_end,
    assert_final_pose,
    assert_finished_within,
    assert_no_collision,
    assert_reached,
    assert_succeeded,
    assert_visited_in_order,
)
from tb4.testing.record import RunRecord
from tb4.testing.simulator import SimSettings, Simulator
from tb4.testing.trials import TIMED_OUT, TrialError, run_mission, run_trial

__all__ = [
    "REACHED",
    "TIMED_OUT",
    "RunRecord",
    "SimSettings",
    "Simulator",
    "TrialError",
    "assert_clearance",
    "assert_docked_at_end",
    "assert_final_pose",
    "assert_finished_within",
    "assert_no_collision",
    "assert_reached",
    "assert_succeeded",
    "assert_visited_in_order",
    "run_mission",
    "run_trial",
]
