"""Sweeps: a mission over many seeds, worlds, batteries and sensing settings, its success rate with its
uncertainty, and every failure with its picture and the command that runs it again.

    from tb4.sweep import Sweep, SweepSpec, build_matrix, parse_seeds
    spec = SweepSpec("nav_to_pose", build_matrix(parse_seeds("0:100"), ["warehouse"]))
    table = Sweep(spec, Path("sweeps/nav")).run()
    print(table.summary()["overall"]["success_rate"])

`tb4 sweep` is the same from the command line; `--ray ADDRESS` runs the trials on a Ray cluster.
"""

from tb4.sweep.matrix import Trial, build_matrix, parse_list, parse_seeds
from tb4.sweep.results import ResultsTable, Row, format_summary, wilson_interval
from tb4.sweep.runner import Sweep, SweepError, SweepSpec, replay_command

__all__ = [
    "ResultsTable",
    "Row",
    "Sweep",
    "SweepError",
    "SweepSpec",
    "Trial",
    "build_matrix",
    "format_summary",
    "parse_list",
    "parse_seeds",
    "replay_command",
    "wilson_interval",
]
