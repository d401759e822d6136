"""Natural-language navigation, safely: programs from a model or the offline interpreter, run by a safe executor.

Modules: executor (validate / plan / execute programs), offline (rule-based interpreter, no network),
model_client (OpenAI-compatible servers through the `openai` SDK), prompt (few-shot context), world_context
(destinations and goal checks from a world file), commands (text -> checked plan -> motion), gpt_node (the ROS
node), scripted_server (a local OpenAI-compatible server for tests and demos). Importing this package does not
import rclpy; only gpt_node does.
"""

from __future__ import annotations

__all__: list[str] = []
