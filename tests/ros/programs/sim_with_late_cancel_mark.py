"""`tb4 sim` (arguments as after `tb4 sim`) whose rclpy marks a goal CANCELING `TB4_TEST_CANCEL_MARK_DELAY` seconds
late: rclpy marks a goal only after the server's cancel callback has returned, in the thread that took the cancel
request, and a thread a loaded machine does not run for a while marks it late. The delay makes that moment last,
so that whatever the server does meanwhile (its loop ending the goal's task, the goal's thread ending the goal)
happens every time."""

from __future__ import annotations

import os
import sys
import time
from typing import Any

from rclpy.action.server import ServerGoalHandle
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from tb4.cli.main import main

DELAY = float(os.environ.get("TB4_TEST_CANCEL_MARK_DELAY", "3.0"))
_update_state = ServerGoalHandle._update_state


def _late_cancel_mark(self: ServerGoalHandle, event: Any) -> None:
    if event == _rclpy.GoalEvent.CANCEL_GOAL:
        time.sleep(DELAY)
    _update_state(self, event)


ServerGoalHandle._update_state = _late_cancel_mark  # type: ignore[method-assign]

if __name__ == "__main__":
    sys.exit(main(["sim", *sys.argv[1:]]))
