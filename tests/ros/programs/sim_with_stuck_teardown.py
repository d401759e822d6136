"""`tb4 sim` (arguments as after `tb4 sim`) whose ROS teardown never ends by itself: the executor's shutdown blocks
in C for `TB4_TEST_STUCK_SECONDS` (default 120) with the GIL held, as a middleware deadlock between threads would.
Everything before it (the run record, the recorders' acknowledgements) runs as usual."""

from __future__ import annotations

import ctypes
import os
import sys

from rclpy.executors import MultiThreadedExecutor

from tb4.cli.main import main

STUCK_SECONDS = int(os.environ.get("TB4_TEST_STUCK_SECONDS", "120"))


def stuck_executor_shutdown(self: MultiThreadedExecutor, *args: object, **kwargs: object) -> bool:
    ctypes.PyDLL(None).sleep(STUCK_SECONDS)  # a PyDLL call keeps the GIL: no Python thread runs meanwhile
    return False


MultiThreadedExecutor.shutdown = stuck_executor_shutdown  # type: ignore[method-assign]

if __name__ == "__main__":
    sys.exit(main(["sim", *sys.argv[1:]]))
