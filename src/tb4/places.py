"""Named places for a mission: ask for "packing station" instead of copying its coordinates from a world file.

On the simulator the places are the world's destinations, found through the simulator's latched `world` topic (no
file path in the script). A real robot has no such topic: there the places come from a destinations file (the
format the language node takes: see tb4.language.site), named in the call or by the TB4_DESTINATIONS environment
variable, so the same script runs on both. Upstream's navigator API is untouched; this is a helper beside it.

A name that is not a place fails when the places are looked up with `require`, before anything moves, with a
"did you mean".

    places = Places.of_robot(namespace=navigator.get_namespace())
    places.require("shelf a", "packing station")
    navigator.startToPose(places.pose("packing station"))
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tb4.config import ConfigError
from tb4.sim.world import Destination, load_world

__all__ = ["Places", "UnknownPlace", "PlacesUnavailable", "DESTINATIONS_ENV", "WORLD_WAIT"]

#: a destinations file for robots that announce no world (a real TurtleBot 4)
DESTINATIONS_ENV = "TB4_DESTINATIONS"
WORLD_WAIT = 5.0  # wall seconds to wait for the simulator's latched `world` message


class UnknownPlace(LookupError):
    """A name that is neither a place nor an alias of one (the message says which names there are)."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


class PlacesUnavailable(RuntimeError):
    """No places to be had: no `world` topic in time and no destinations file, or a file that does not load."""


def _key(name: str) -> str:
    """Names compare without case, and with blanks, underscores and hyphens alike ("Loading_Bay" = "loading bay")."""
    return " ".join(name.lower().replace("_", " ").replace("-", " ").split())


@dataclass(frozen=True)
class Places:
    """A site's named places (pose in the map frame, yaw in radians, aliases) and where they came from."""

    destinations: tuple[Destination, ...]
    source: str = ""

    # ---------------------------------------------------------------------------------------------- loading
    @classmethod
    def of_world(cls, world: str | Path) -> Places:
        """The places of a simulator world, by name (warehouse, depot, maze) or world file.

        Raises:
            PlacesUnavailable: the world does not load (the message names the file and the key).
        """
        try:
            loaded = load_world(world)
        except (ConfigError, OSError, ValueError) as exc:
            raise PlacesUnavailable(str(exc)) from None
        return cls(tuple(loaded.destinations.values()), f"world {loaded.name}")

    @classmethod
    def from_file(cls, path: str | Path) -> Places:
        """The places of a destinations file (a real robot's site: see tb4.language.site).

        Raises:
            PlacesUnavailable: the file does not load (the message names the file and the key).
        """
        from tb4.language.site import load_site_file

        try:
            site = load_site_file(path)
        except (ConfigError, OSError, ValueError) as exc:
            raise PlacesUnavailable(str(exc)) from None
        return cls(tuple(site.destinations.values()), site.source)

    @classmethod
    def of_robot(
        cls, namespace: str = "", destinations: str | Path | None = None, timeout: float = WORLD_WAIT
    ) -> Places:
        """The places where the robot is: a destinations file if one is named (here or in TB4_DESTINATIONS),
        else the world the simulator announces on its latched `world` topic.

        Args:
            namespace: the robot's namespace (a fleet robot's: "/robot1"); a navigator's get_namespace().
            destinations: a destinations file, for a robot that announces no world.
            timeout: wall seconds to wait for the `world` message.

        Returns:
            The Places.

        Raises:
            PlacesUnavailable: no file, and no world announced within `timeout` (a real robot announces none),
                or the world switched to a map it does not describe.
        """
        chosen = destinations or os.environ.get(DESTINATIONS_ENV, "").strip()
        if chosen:
            return cls.from_file(chosen)
        reference = _announced_world(namespace, timeout)
        if reference is None:
            raise PlacesUnavailable(
                f"no world announced on '{_topic(namespace)}' within {timeout:g} s (a real robot announces none): "
                f"name a destinations file (Places.of_robot(destinations='site.yaml') or {DESTINATIONS_ENV}=FILE)"
            )
        if not reference:
            raise PlacesUnavailable("the simulator switched to a map its world does not describe: no named places")
        return cls.of_world(reference)

    # ---------------------------------------------------------------------------------------------- lookup
    @property
    def names(self) -> list[str]:
        """Every place's name, in the file's order."""
        return [d.name for d in self.destinations]

    def __iter__(self) -> Iterator[Destination]:
        return iter(self.destinations)

    def __len__(self) -> int:
        return len(self.destinations)

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and self._find(name) is not None

    def _find(self, name: str) -> Destination | None:
        key = _key(name)
        for dest in self.destinations:
            if key == _key(dest.name) or key in (_key(a) for a in dest.aliases):
                return dest
        return None

    def get(self, name: str) -> Destination:
        """The place called `name` (or one of its aliases; case, blanks and underscores do not matter).

        Raises:
            UnknownPlace: no such place; the message suggests the closest name and lists them all.
        """
        found = self._find(name)
        if found is not None:
            return found
        words = {_key(word): d.name for d in self.destinations for word in (d.name, *d.aliases)}
        close = difflib.get_close_matches(_key(name), list(words), n=1, cutoff=0.6)
        hint = f"did you mean '{words[close[0]]}'? " if close else ""
        raise UnknownPlace(f"no place called {name!r} in {self.source or 'these places'}; {hint}places: {self.names}")

    def require(self, *names: str | Iterable[str]) -> list[Destination]:
        """Check every name at once, before the robot moves; the places in order.

        Raises:
            UnknownPlace: the first unknown name (each message has its "did you mean").
        """
        flat = [n for item in names for n in ([item] if isinstance(item, str) else item)]
        unknown = [name for name in flat if self._find(name) is None]
        if unknown:
            problems = []
            for name in unknown:
                try:
                    self.get(name)
                except UnknownPlace as exc:
                    problems.append(str(exc))
            raise UnknownPlace(problems[0] if len(problems) == 1 else "; ".join(problems))
        return [self.get(name) for name in flat]

    def xy_yaw(self, name: str) -> tuple[float, float, float]:
        """(x, y, yaw) of a place in the map frame (yaw in radians)."""
        dest = self.get(name)
        return (dest.x, dest.y, dest.yaw)

    def pose(self, name: str, navigator: Any = None, frame_id: str = "map") -> Any:
        """The place as a geometry_msgs PoseStamped goal for the navigator.

        Args:
            name: the place (or an alias).
            navigator: stamps the pose with its clock's now (as upstream's getPoseStamped); None: stamp 0.
            frame_id: the pose's frame.

        Returns:
            A PoseStamped.

        Raises:
            UnknownPlace: no such place.
        """
        from tb4.ros.convert import pose_stamped

        x, y, yaw = self.xy_yaw(name)
        msg = pose_stamped((x, y, yaw), frame_id=frame_id)
        if navigator is not None:
            msg.header.stamp = navigator.get_clock().now().to_msg()
        return msg


def _topic(namespace: str) -> str:
    ns = namespace.strip("/")
    return f"/{ns}/world" if ns else "/world"


def _announced_world(namespace: str, timeout: float) -> str | None:
    """The latched `world` message of the simulator serving `namespace` (None: none within `timeout`)."""
    import threading

    from std_msgs.msg import String

    from tb4.ros.background import BackgroundNode
    from tb4.ros.qos import LATCHED
    from tb4.ros.world_topic import WORLD_TOPIC
    from tb4.rosenv import apply_safe_ros_defaults

    apply_safe_ros_defaults()
    received: list[str] = []
    arrived = threading.Event()
    background = BackgroundNode("tb4_places", namespace, signal_handlers=False)
    try:

        def on_world(msg: Any) -> None:
            received.append(msg.data)
            arrived.set()

        background.node.create_subscription(String, WORLD_TOPIC, on_world, LATCHED)
        background.start()
        arrived.wait(timeout)
    finally:
        background.close()
    return received[0] if received else None
