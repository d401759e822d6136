"""Upstream import path `turtlebot4_navigation`, served by tb4's navigator so existing scripts run unchanged."""

__all__: list[str] = []
