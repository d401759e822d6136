"""Upstream import path `nav2_simple_commander`, served by tb4's navigator so existing scripts run unchanged."""

__all__: list[str] = []
