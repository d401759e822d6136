"""Every bound the safe executor enforces, in one place (the README's limits table mirrors this file).

A program comes from a language model or from whoever can publish on `user_input`, so each stage has a budget
that no program, however small, can exceed: the source and its syntax tree (validate), the values it builds,
the work it does, and the CPU time (with a wall-clock backstop) and memory planning takes (plan), and the robot
time it may use (execute).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Limits", "DEFAULT_LIMITS"]


@dataclass(frozen=True)
class Limits:
    """Bounds on a program. Sizes are in cells: a number, None or a pose is 1 cell, a string 1 + its length,
    a list or tuple 1 + the cells of each element, a dict 1 + the cells of each key and value. A value reachable
    twice (``A = [B, B]``) is counted twice, so sharing cannot hide size."""

    # -- validate: the text and its syntax tree -----------------------------------------------------------------
    max_chars: int = 4000  #: characters of source
    max_nodes: int = 1500  #: syntax-tree nodes
    max_depth: int = 30  #: syntax-tree nesting
    max_statements: int = 40  #: top-level statements
    # -- plan: values, work, time and memory --------------------------------------------------------------------
    max_list: int = 200  #: elements of one list, tuple or dict
    max_string: int = 500  #: characters of one string
    max_abs_number: float = 1e6  #: magnitude of any number
    max_value_cells: int = 5000  #: cells of one value, shared references counted each time they are reachable
    max_value_depth: int = 8  #: nesting of lists in one value
    max_total_cells: int = 100_000  #: cells allocated by the whole program (the planner's memory bound)
    max_eval_ops: int = 20_000  #: evaluation steps
    max_plan_seconds: float = 0.5  #: CPU time of the planning thread for validating and planning one program
    max_plan_wall_seconds: float = 5.0  #: wall-clock backstop: a run starved of CPU or blocked in a pose check
    max_message: int = 300  #: characters of any refusal reason, and of any value shown in one
    # -- plan: what the program asks of the robot ---------------------------------------------------------------
    max_goals: int = 20  #: goal poses sent (startToPose counts 1, a list of poses counts each)
    max_steps: int = 30  #: robot actions (navigator calls) in one plan
    # -- execute ------------------------------------------------------------------------------------------------
    max_run_seconds: float = 300.0  #: wall-clock budget for running the whole plan
    max_task_seconds: float = 180.0  #: longest wait for one navigation goal; a behaviour waits its time_allowance
    task_grace_seconds: float = 5.0  #: extra wait past a behaviour's time_allowance, and for a cancel to land
    poll_seconds: float = 0.1  #: longest pause between completion checks (each wakes at once on a stop request)

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                raise ValueError(f"Limits.{name} must be a non-negative number, got {value!r}")
            if value == float("inf"):
                raise ValueError(f"Limits.{name} must be finite: a limit that does not bound is not a limit")


DEFAULT_LIMITS = Limits()
