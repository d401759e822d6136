"""Ready-made display configurations for the topics the simulator serves (and a TurtleBot 4 publishes).

FOXGLOVE_LAYOUT is a layout for the Foxglove app (import it from the app's Layouts menu) and the data `tb4 sim
--foxglove` serves; RVIZ_CONFIG is an RViz 2 configuration for users with ROS installed (`rviz2 -d`). Both name the
topics without a namespace, as `tb4 sim` serves one robot by default.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["DISPLAYS_DIR", "FOXGLOVE_LAYOUT", "RVIZ_CONFIG"]

DISPLAYS_DIR: Path = Path(__file__).resolve().parent
FOXGLOVE_LAYOUT: Path = DISPLAYS_DIR / "foxglove_layout.json"
RVIZ_CONFIG: Path = DISPLAYS_DIR / "turtlebot4.rviz"
