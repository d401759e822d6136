"""The `world` topic: which tb4 world the simulator serves, so a viewer shows its dock, named places and route
graph without guessing from the map. Latched std_msgs/String: a shipped world's name, another world file's path,
or "" once map_server/load_map has switched to a map the world does not describe. A real robot has no such topic;
the viewer then works from /map alone.

A fleet's robots also announce the fleet on `fleet` (latched std_msgs/String): every robot's namespace in the one
world, space-separated, in the fleet's order ("/robot1 /robot2 /robot3"), so a viewer of one robot shows them all
and gives each its colour. A one-robot simulator (and a real robot) has no `fleet` topic."""

from __future__ import annotations

import re
from pathlib import Path

from rclpy.node import Node
from std_msgs.msg import String

from tb4.ros.qos import LATCHED
from tb4.sim.world import WORLDS_DIR, World

__all__ = ["WORLD_TOPIC", "FLEET_TOPIC", "WorldAnnouncer", "world_reference", "fleet_text", "parse_fleet"]

WORLD_TOPIC = "world"
FLEET_TOPIC = "fleet"


def fleet_text(namespaces: tuple[str, ...]) -> str:
    """What `fleet` carries: the namespaces, space-separated (a namespace never holds a space)."""
    return " ".join(namespaces)


#: A `fleet` message is a string anyone on the domain can publish, and a viewer subscribes per robot it names:
#: only valid ROS namespaces count, and no more than this many (a classroom fleet is far smaller).
MAX_FLEET = 64
_NAMESPACE = re.compile(r"(/[A-Za-z][A-Za-z0-9_]{0,63}){1,8}")


def parse_fleet(text: str) -> tuple[str, ...]:
    """The valid namespaces a `fleet` message names, in order, each once, at most MAX_FLEET."""
    valid = (part for part in text.split() if _NAMESPACE.fullmatch(part))
    return tuple(dict.fromkeys(valid))[:MAX_FLEET]


def world_reference(world: World) -> str:
    """What tb4.sim.world.load_world needs to load `world` again: its name if shipped, else its file's path."""
    source = Path(world.source).resolve()
    shipped = (WORLDS_DIR / f"{source.stem}.yaml").resolve()
    return source.stem if source == shipped else str(source)


class WorldAnnouncer:
    """Publishes the simulator's world on `world` (latched) from `node`, and the fleet it is part of on `fleet`."""

    def __init__(self, node: Node, world: World, fleet: tuple[str, ...] = ()) -> None:
        self._pub = node.create_publisher(String, WORLD_TOPIC, LATCHED)
        self.announce(world_reference(world))
        if fleet:
            self._fleet_pub = node.create_publisher(String, FLEET_TOPIC, LATCHED)
            self._fleet_pub.publish(String(data=fleet_text(fleet)))

    def announce(self, reference: str) -> None:
        self._pub.publish(String(data=reference))

    def withdraw(self) -> None:
        """The map changed under the world (load_map): its places no longer apply."""
        self.announce("")
