"""Nav2's nodes, actions, services and topics in the simulator, one module per server (see interfaces.py)."""

from tb4.ros.nav2.interfaces import Nav2Interfaces
from tb4.ros.nav2.lifecycle import LOCALIZATION_NODES, NAVIGATION_NODES

__all__ = ["Nav2Interfaces", "NAVIGATION_NODES", "LOCALIZATION_NODES"]
