"""Natural-language navigation, safely: programs from a model or the offline interpreter, run by a safe executor.

The safe executor: executor (the three stages in one call, and their public names), validate (is it our
language), plan, budget and steps (evaluate it on plain data within budgets; bind navigator calls into steps),
execute (run a plan on the navigator), bounded_format (the one formatter for values a program can show),
vocabulary (allowed methods, plan types, errors), limits (every bound, in one place).
Around it: offline (rule-based interpreter, no network),
model_client (OpenAI-compatible servers through the `openai` SDK), prompt (few-shot context), world_context
(destinations and goal checks from a world file), commands (text -> checked plan -> motion), gpt_node (the ROS
node), scripted_server (a local OpenAI-compatible server for tests and demos). Importing this package, and
validating or planning a program, does not import rclpy; gpt_node does, and so does executing a plan (to compare
results with the navigator's TaskResult).
"""

from __future__ import annotations

__all__: list[str] = []
