"""The tests whose subject never touches nav2_msgs run in one make test stage only (the Makefile's
KILTED_STAGE_ONLY and JAZZY_STAGE_ONLY): one run covers both builds only if every other package they load is the
same files in both. Run in each environment (make test runs it in both stages): the Jazzy overlay must hold its own
nav2_msgs and take every other interface package and rclpy from the Kilted environment it overlays."""

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


def test_only_nav2_msgs_differs_between_the_two_environments() -> None:
    pytest.importorskip("nav2_msgs", reason="ROS interface packages not installed")
    overlay = importlib.util.find_spec("tb4_venv_overlay") is not None
    assert _inside("nav2_msgs", sys.prefix)  # each environment's own wire format
    for module in SHARED:
        # the overlay finds them in the base environment, the base holds them itself
        assert _inside(module, sys.prefix) != overlay, (module, importlib.import_module(module).__file__, sys.prefix)
