"""The tests whose subject never touches nav2_msgs run in one make test stage only (the Makefile's
KILTED_STAGE_ONLY and JAZZY_STAGE_ONLY), and the stages run on the middleware they are named for. Run in each
environment (make test runs it in both stages): a whole environment holds its own rclpy and every interface package,
of one distribution, whose nav2_msgs wire format is its own (Kilted's, or ROS 2 Jazzy's own middleware with Jazzy's);
an overlay (the Jazzy wire environment of the cross-distro stage) holds only its nav2_msgs and takes the rest from the
environment it overlays."""

from __future__ import annotations

import importlib
import importlib.util
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.core

# what the one-stage tests import besides tb4 (whose sources both environments install editable from src/)
SHARED = ("rclpy", "irobot_create_msgs", "geometry_msgs", "nav_msgs", "sensor_msgs", "std_msgs", "tf2_msgs")


def _inside(module: str, prefix: str) -> bool:
    return Path(importlib.import_module(module).__file__ or "").resolve().is_relative_to(Path(prefix).resolve())


def test_each_environment_holds_the_middleware_and_wire_format_of_its_stage() -> None:
    pytest.importorskip("nav2_msgs", reason="ROS interface packages not installed")
    from tb4.rosenv import installed_middleware, middleware_problems
    from tb4.wire import wire_format

    overlay = importlib.util.find_spec("tb4_venv_overlay") is not None
    assert _inside("nav2_msgs", sys.prefix)  # each environment's own wire format
    for module in SHARED:
        # the overlay finds them in the base environment, a whole environment holds them itself
        assert _inside(module, sys.prefix) != overlay, (module, importlib.import_module(module).__file__, sys.prefix)
    middleware = installed_middleware()
    assert middleware_problems(middleware) == []
    if not overlay:  # a whole environment speaks its own distribution's nav2_msgs
        assert middleware.distro == wire_format(), middleware.describe()
