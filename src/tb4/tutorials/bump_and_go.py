"""Bump and go: undock, drive straight until the bumper touches something, back off, turn away from the side
that touched, and go again; three bumps, then a tune. Uses only the Create 3's own API (hazard_detection,
drive_distance, rotate_angle, cmd_lightring, audio_note_sequence): no Nav2, no map."""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Sequence
from typing import Any

from tb4.core.units import seconds_of
from tb4.rosenv import apply_safe_ros_defaults, require_ros
from tb4.tutorials.common import tutorial_arguments

__all__ = ["WORLD", "BUMPS", "main", "turn_for"]
WORLD = "depot"
BUMPS = 3
BACK_OFF = 0.15  # m reversed after a bump (well inside the Create 3's backup limit)
RUN = 20.0  # m asked for each straight run: it ends at the next bump
RUN_TIMEOUT = 300.0  # wall s one straight run may take (20 m at 0.3 m/s is 67 s of sim time)
BUMP, CLIFF = 1, 2


def turn_for(frame: str, count: int) -> float:
    """Turn (rad) away from the bumper zone that touched; head-on bumps alternate sides."""
    if frame.endswith(("_left", "front_left")):
        return -math.radians(100)
    if frame.endswith(("_right", "front_right")):
        return math.radians(100)
    return math.radians(150) * (1 if count % 2 else -1)


class BumpAndGo:
    def __init__(self, namespace: str) -> None:
        from irobot_create_msgs.action import AudioNoteSequence, DriveDistance, RotateAngle, Undock
        from irobot_create_msgs.msg import HazardDetectionVector, LightringLeds

        from tb4.ros.action_client import ActionClient  # rclpy's, with a race of send_goal_async closed
        from tb4.ros.background import BackgroundNode

        self._background = BackgroundNode("bump_and_go", namespace)  # spins in a thread; main() waits on futures
        self.node = self._background.node
        self.lock = threading.Lock()
        self.touch: tuple[str, float] | None = None  # bumper zone (or cliff sensor) of the first new hazard, when
        self.since = -math.inf  # the robot's time from which a hazard is news (watch_from)
        self._sim_clock = False  # this node follows the simulator's /clock (run_start)
        self.node.create_subscription(HazardDetectionVector, "hazard_detection", self._on_hazards, 10)
        self.ring = self.node.create_publisher(LightringLeds, "cmd_lightring", 10)
        self.clients: dict[str, Any] = {
            "undock": ActionClient(self.node, Undock, "undock"),
            "drive_distance": ActionClient(self.node, DriveDistance, "drive_distance"),
            "rotate_angle": ActionClient(self.node, RotateAngle, "rotate_angle"),
            "audio_note_sequence": ActionClient(self.node, AudioNoteSequence, "audio_note_sequence"),
        }
        self.types = {"undock": Undock, "drive_distance": DriveDistance, "rotate_angle": RotateAngle}
        self.types["audio_note_sequence"] = AudioNoteSequence
        self._background.start()

    def log(self, text: str) -> None:
        self.node.get_logger().info(text)

    def _on_hazards(self, msg: Any) -> None:
        for d in msg.detections:
            if d.type in (BUMP, CLIFF):
                stamp = seconds_of(d.header.stamp)
                with self.lock:
                    if self.touch is None and stamp >= self.since:
                        self.touch = (d.header.frame_id.rsplit("/", 1)[-1], stamp)

    def watch_from(self, stamp: float) -> None:
        """Take hazards detected from `stamp` (a run's start, in the robot's time) on as news. The bumper stays
        pressed until the robot has backed off, and the last contact's messages can still be queued for this node
        when the next run starts (at --rate max the back-off and turn take a few wall milliseconds, and a loaded
        machine delays delivery more): they are old news, not a bump of the new run."""
        with self.lock:
            self.since = stamp
            if self.touch is not None and self.touch[1] < stamp:
                self.touch = None

    def run_start(self) -> float | None:
        """The simulator's time now, for watch_from, or None when no simulator publishes /clock (a robot's hazard
        stamps are then its own clock's, as are its goals': see main). This node follows /clock from the first call
        that finds it published."""
        if not self._sim_clock and self.node.count_publishers("/clock") > 0:
            from rclpy.parameter import Parameter

            with self._background.paused():  # following /clock subscribes to it
                self.node.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
            self._sim_clock = True
        return seconds_of(self.node.get_clock().now().to_msg()) if self._sim_clock else None

    def take_touch(self) -> str | None:
        with self.lock:
            touch, self.touch = self.touch, None
            return None if touch is None else touch[0]

    def goal(self, name: str, timeout: float = 120.0, **fields: Any) -> tuple[Any, Any]:
        """Send a goal and return (goal handle, result future)."""
        from tb4.core.waits import wait_for_future

        client = self.clients[name]
        if not client.wait_for_server(timeout_sec=30.0):
            raise RuntimeError(
                f"no '{name}' action server ready in 30 s: is the simulator (or the robot) running? "
                f"(the graph shows {client.graph_report()})"
            )
        handle = wait_for_future(client.send_goal_async(self.types[name].Goal(**fields)), 10.0, f"{name} acceptance")
        if not handle.accepted:
            raise RuntimeError(f"{name} goal rejected")
        return handle, handle.get_result_async()

    def run_goal(self, name: str, timeout: float = 120.0, **fields: Any) -> int:
        from tb4.core.waits import wait_for_future

        _, future = self.goal(name, **fields)
        return int(wait_for_future(future, timeout, f"{name} result").status)

    def lights(self, rgb: tuple[int, int, int] | None) -> None:
        from irobot_create_msgs.msg import LedColor, LightringLeds

        msg = LightringLeds(override_system=rgb is not None)
        if rgb is not None:
            msg.leds = [LedColor(red=rgb[0], green=rgb[1], blue=rgb[2])] * 6
        self.ring.publish(msg)

    def close(self) -> None:
        self._background.close()


def main(argv: Sequence[str] | None = None) -> int:
    args = tutorial_arguments(__doc__ or "", argv)
    apply_safe_ros_defaults()
    require_ros()
    from tb4.core.waits import wait_for_future

    robot = BumpAndGo(args.namespace)
    try:
        robot.log("Undocking")
        if robot.run_goal("undock") != 4:
            robot.node.get_logger().error("undock failed")
            return 1
        bumps = 0
        while bumps < BUMPS:
            robot.lights((0, 255, 0))
            started = robot.run_start()
            handle, future = robot.goal("drive_distance", distance=RUN, max_translation_speed=0.3)
            # a robot stamps its hazards and accepted goals with its own clock (a laptop's may differ), while the
            # simulator stamps its goals in wall time and its hazards in sim time
            robot.watch_from(seconds_of(handle.stamp) if started is None else started)
            touch = None
            deadline = time.monotonic() + RUN_TIMEOUT
            while not future.done():
                touch = robot.take_touch()
                if touch is not None:
                    break
                if time.monotonic() > deadline:
                    robot.node.get_logger().error(f"no bump and no end of the run after {RUN_TIMEOUT:g} s")
                    return 1
                time.sleep(0.01)
            if touch is None:  # the run ended without a bump (or aborted on a stall): look for the reason
                touch = robot.take_touch() or "bump_front_center"
            bumps += 1
            robot.lights((255, 0, 0))
            robot.log(f"Bump {bumps} on {touch}: backing off and turning away")
            if not future.done():
                wait_for_future(handle.cancel_goal_async(), 10.0, "cancel the run")
                wait_for_future(future, 30.0, "the canceled run")
            if robot.run_goal("drive_distance", distance=-BACK_OFF, max_translation_speed=0.2) != 4:
                robot.node.get_logger().error("could not back off")
                return 1
            if robot.run_goal("rotate_angle", angle=turn_for(touch, bumps)) != 4:
                robot.node.get_logger().error("could not turn away")
                return 1
        from irobot_create_msgs.msg import AudioNote, AudioNoteVector

        from tb4.ros.convert import duration_msg

        # The ring goes back to the robot before the tune, not as the last thing before exit: the Create 3 reads
        # cmd_lightring best effort, and a sample sent just before the process ends can be lost (seen under load).
        robot.lights(None)
        tune = AudioNoteVector(notes=[AudioNote(frequency=f, max_runtime=duration_msg(0.2)) for f in (392, 523, 659)])
        robot.run_goal("audio_note_sequence", iterations=1, note_sequence=tune)
        robot.log(f"Done: {bumps} bumps handled")
        return 0
    finally:
        robot.close()


if __name__ == "__main__":
    sys.exit(main())
