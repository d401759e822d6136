"""The simulator process: world + robot + Nav2-compatible navigation, served over ROS 2 until stopped.

    tb4 sim --world depot --rate max --namespace robot1
    tb4 sim --world warehouse --robots 3          # robot1..robot3 on the first three docks

Everything is named relative to the namespace, like a namespaced TurtleBot 4. A fleet (--robots N, or the robots
a world file lists) serves every robot under its own namespace from this one process, on one loop and one /clock.
Ctrl-C (SIGINT) or SIGTERM stop it cleanly.
"""

from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from tb4.extras import MissingExtraError, require_extra
from tb4.foxglove import FoxgloveError, FoxgloveOptions
from tb4.nav.route_graph import load_route_graph
from tb4.processes import CONTROL_REPLY, READY_LINE, abandoned_ports_watched, exit_within
from tb4.replay.core_world import CoreSettings, build_core_world
from tb4.replay.journal import InputJournal, journal_path_for
from tb4.ros.loop import LoopStopped, LoopView, RobotLoop, SimLoop
from tb4.ros.replies import create_service
from tb4.ros.run_record import RunRecord
from tb4.ros.served_robot import ServedRobot
from tb4.ros.sim_node import SimNode
from tb4.ros.stall_report import ExecutorQueueWatch
from tb4.sim.fleet import Fleet
from tb4.sim.world import World, load_world

if TYPE_CHECKING:
    from tb4.runner.mcap_record import PublicationLedger

__all__ = ["SimulatorOptions", "Simulator", "main", "parse_rate", "serve_control", "READY_LINE", "CONTROL_REPLY"]

RECORDER_STARTUP_TIMEOUT = 10.0  # wall seconds for the latched map and static transforms to reach a recording
# wall seconds the simulator's shutdown waits for a recorder to have acknowledged every message of its reliable topics
DELIVERY_TIMEOUT = 3.0
STOP_LOOK_PERIOD = 0.5  # wall seconds between two looks at the loop and the context while serving (a stop: at once)
SERVE_TURN_TIMEOUT = 1.0  # wall seconds an idle executor turn waits (a stop ends it at once: spin)
SERVE_END_TIMEOUT = 5.0  # wall seconds for the executor's thread to end its turn once woken
# wall seconds for the process to end once its run is finished (the executor, the nodes, rclpy, the interpreter)
TEARDOWN_TIMEOUT = 10.0


def parse_rate(text: str | float) -> float:
    """'1' -> 1.0, '20' -> 20.0, 'max' -> inf (as fast as possible)."""
    if isinstance(text, (int, float)):
        value = float(text)
    elif str(text).strip().lower() in ("max", "inf", "fast"):
        return math.inf
    else:
        try:
            value = float(text)
        except ValueError:
            raise ValueError(f"rate must be a positive number or 'max', got {text!r}") from None
    if not (value > 0) or math.isnan(value):
        raise ValueError(f"rate must be a positive number or 'max', got {text!r}")
    return value


def normalize_namespace(namespace: str) -> str:
    ns = namespace.strip().strip("/")
    if ns and not all(part.isidentifier() for part in ns.split("/")):
        raise ValueError(f"invalid namespace {namespace!r}: use letters, digits and underscores, e.g. robot1")
    return f"/{ns}" if ns else ""


@dataclass
class SimulatorOptions:
    world: str = "warehouse"
    rate: float = 1.0
    seed: int = 0
    namespace: str = ""
    robots: int = 0  # N > 0: a fleet robot1..robotN on the world's first N docks (0: the world's robots, or one)
    battery: float | None = None
    physics_dt: float = 0.01
    record_run: Path | None = None
    view_port: int | None = None  # serve the web viewer on this port
    record: Path | None = None  # record the robots' topics to this MCAP file (as `tb4 run --record`)
    foxglove: FoxgloveOptions | None = None  # serve the robots' topics to the Foxglove app
    hold: bool = False  # run at real time until the first goal (the initial pose is still start-up)
    exact: bool = False  # no odometry drift and no lidar noise (the default is the seeded noise models)
    # amcl (the particle filter, as upstream) | truth (the simulator's true pose) | odometry (dead reckoning)
    localization: str = "amcl"
    replay: Path | None = None  # a run's input journal: apply its inputs on their ticks, stop after its last
    # world resets and record writes asked for on standard input, one JSON line each (tb4 sweep's; serve_control)
    control: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


class Simulator:
    """Builds the world, the loop and the ROS interfaces in one rclpy context."""

    def __init__(self, options: SimulatorOptions, context: Any | None = None) -> None:
        self.options = options
        self.namespace = normalize_namespace(options.namespace)
        self.world: World = load_world(options.world)
        # a broken route graph stops the start like a broken map does: the file, the feature, the problem
        self.route_graph = load_route_graph(self.world.route_graph) if self.world.route_graph is not None else None
        self.core_settings = CoreSettings(
            seed=options.seed,
            robots=options.robots,
            namespace=options.namespace,
            battery=options.battery,
            physics_dt=options.physics_dt,
            exact=options.exact,
            localization=options.localization,
        )
        core = build_core_world(self.world, self.core_settings)
        self.fleet: Fleet | None = core.fleet
        sims, navs = core.sims, core.navs
        views: list[LoopView]
        if core.fleet is not None:
            self.loop = SimLoop(sims[0], navs[0], rate=options.rate, hold=options.hold, world=core.fleet, navs=navs)
            views = [self.loop, *(RobotLoop(self.loop, sim, nav) for sim, nav in zip(sims[1:], navs[1:], strict=True))]
            namespaces = [spec.namespace for spec in core.specs]
        else:
            self.loop = SimLoop(sims[0], navs[0], rate=options.rate, hold=options.hold)
            views, namespaces = [self.loop], [self.namespace]
        self.sim, self.nav = self.loop.sim, self.loop.nav  # the (first) robot's
        if options.replay is not None:
            from tb4.replay.engine import ReplayFeed
            from tb4.replay.journal import read_journal

            feed = ReplayFeed(read_journal(options.replay), len(sims))
            feed.before_tick(self.loop, 0)
            self.loop.feed = feed
        self.context = context or rclpy.get_default_context()
        fleet = tuple(namespaces) if self.fleet is not None else ()
        self.record = (
            RunRecord(self.world.name, options.record_run, fleet, world_file=self.world.source.resolve())
            if options.record_run
            else None
        )
        if self.record is not None:
            self.record.docks = list(self.world.all_docks)
            self.loop.every(0.2, self._record_sample)
            # what the world received, tick by tick: `tb4 replay` re-runs the run from it
            self.loop.journal = InputJournal(
                {
                    "world": self.world.name,
                    "world_file": str(self.world.source.resolve()),
                    "rate": "max" if math.isinf(options.rate) else options.rate,
                    "control_period": self.loop.control_period,
                    **self.core_settings.to_json(),
                }
            )
        record = self.record
        # what the nodes send on the recorded topics, counted from each publisher's first message: a recording (this
        # process's, or `tb4 run`'s through the run record) is checked against it when the simulator stops
        self.ledger: PublicationLedger | None = None
        self.recording: dict[str, Any] | None = None  # the report of this process's recording, for the run record
        self._delivered = False
        self._finished = False  # finish_run has written the record
        self._record_final = False  # the run's record is written for good (write_record(final=True)) until a reset
        if options.record_run or options.record:
            from tb4.runner.mcap_record import PublicationLedger

            self.ledger = PublicationLedger(namespaces)
        with self.ledger.counting(SimNode) if self.ledger is not None else contextlib.nullcontext():
            self.robots = [
                ServedRobot(
                    self.context,
                    view,
                    self.world,
                    self.route_graph,
                    ns,
                    record=record.robot(ns) if record else None,
                    clock=k == 0,
                    fleet=fleet,
                )
                for k, (view, ns) in enumerate(zip(views, namespaces, strict=True))
            ]
        if self.ledger is not None:
            self.ledger.watch_subscriptions(self.all_nodes())
        first = self.robots[0]
        self.namespace = first.namespace
        self.robot_node, self.create3, self.nav2 = first.node, first.create3, first.nav2
        self.world_topic, self.routes, self.gps, self.ground_truth = (
            first.world_topic,
            first.routes,
            first.gps,
            first.ground_truth,
        )
        logger = self.robot_node.get_logger()

        def report(text: str) -> None:
            logger.warn(text)

        self.loop.report = report
        self.seed = options.seed  # the seed of the run served now (a world reset takes another)
        self.robot_node.declare_parameter("seed", options.seed)
        create_service(self.robot_node, Trigger, "reset_world", self._on_reset_world)
        self.executor = MultiThreadedExecutor(num_threads=8, context=self.context)
        for node in self.all_nodes():
            self.executor.add_node(node)
        # triggered to end the executor's turn (spin): a guard condition with a callback is work, which ends a turn,
        # where executor.wake() only makes rclpy wait again, to the turn's timeout, when nothing else is ready
        self._end_turn = self.robot_node.create_guard_condition(lambda: None)

    def all_nodes(self) -> list[Node]:
        return [node for robot in self.robots for node in robot.nodes()]

    def _record_sample(self, now: float) -> None:
        """Every robot's true pose, localization estimate and recoveries, into its part of the record."""
        assert self.record is not None
        for robot in self.robots:
            part = self.record.robot(robot.namespace)
            pose = robot.sim.pose()
            part.sample(now, pose.x, pose.y, pose.yaw)
            part.battery_level(now, robot.sim.battery().percentage)
            if not robot.sim.is_docked():
                part.clearance_sample(now, robot.sim.clearance_at(pose.x, pose.y) - robot.sim.params.drive.radius)
            estimate = robot.nav.pose()
            if estimate is not None:
                part.estimate(now, *estimate)
            if robot.nav.task is not None:
                part.task_progress(robot.nav.task, now, pose.x, pose.y)

    def start(self) -> None:
        self.loop.start()

    def reset_world(self, seed: int | None = None, record_run: Path | None = None) -> None:
        """Back to the world as this simulator built it, with `seed` (default: the `seed` parameter of the robot's
        node, which starts as --seed): robot, battery, obstacles, localization, costmaps, tasks and the clock (to 0),
        as a new `tb4 sim` with that seed (SimLoop.reset). Every running goal ends (aborted); amcl_pose is
        withdrawn until a new initial pose. The run record starts again, to `record_run` if given; what it held is
        dropped (`write_record` first keeps it). One robot only.

        Args:
            seed: the new run's seed (0 .. 2**32 - 1).
            record_run: where the new run's record goes (default: where the last one went).

        Raises:
            ValueError: a fleet, or a seed out of range.
        """
        if self.fleet is not None:
            raise ValueError("a fleet's world cannot be reset: start a new simulator")
        if seed is None:
            seed = int(self.robot_node.get_parameter("seed").value)
        if not (0 <= seed < 2**32):
            raise ValueError(f"seed must be between 0 and 2**32 - 1, got {seed}")
        self.loop.reset(seed)
        self.seed = seed
        if self.record is not None:
            self.record.restart(record_run)
            self._record_final = False

    def _on_reset_world(self, _request: Any, response: Any) -> Any:
        """reset_world (std_srvs/Trigger): `reset_world` with the seed of the `seed` parameter."""
        try:
            self.reset_world()
        except (ValueError, LoopStopped, TimeoutError) as exc:
            response.success, response.message = False, f"reset_world refused: {exc}"
            return response
        response.success, response.message = True, f"world {self.world.name} reset: seed {self.seed}, sim time 0"
        self.robot_node.get_logger().info(response.message)
        return response

    def write_record(self, final: bool = False) -> Path | None:
        """Write the run record now (as at the end), with the input journal beside it: what a world reset would
        otherwise drop. None without one, when its folder no longer exists, or after a final write.

        Args:
            final: the run is over (a sweep's trial ended): no later write (at close) rewrites this record with
                the ticks that follow, until a world reset starts the next run.
        """
        if self.record is None or self._record_final or not self.record.path.parent.is_dir():
            return None  # none kept, written for good, or its folder is gone (a sweep drops a successful trial's)
        self._record_final = final
        journal = self.loop.journal
        if journal is not None:
            with self.loop.lock:  # between two ticks: the digest, the tick count and the checkpoints agree
                path = journal.write(journal_path_for(self.record.path))
                end = journal.end()
            self.record.replay = {
                "journal": path.name,
                "inputs": len(journal.inputs),
                "ticks": end.ticks,
                "digest": end.digest,
                "untracked": list(end.untracked),
                "left_out": list(end.left_out),
            }
        return self.record.write(
            {
                "sim_time": self.sim.time,
                "real_time_factor": self.loop.real_time_factor,
                "bumps": self.create3.bumps,
                "docked": self.sim.is_docked(),
                "battery": self.sim.battery().percentage,
                "localization": self.options.localization,
                "exact": self.options.exact,
                "seed": self.seed,
                **({"fleet": self._fleet_summary()} if self.fleet is not None else {}),
                **({"published": self.ledger.snapshot()} if self.ledger is not None else {}),
                **({"first_sent_ns": self.ledger.first_sent()} if self.ledger is not None else {}),
                **({"recording": self.recording} if self.recording is not None else {}),
            }
        )

    def spin(self, stop: threading.Event | None = None) -> None:
        """Serve until `stop` is set, the context shuts down, or the loop dies.

        The executor turns in a thread of its own, and wakes only for work: each turn rebuilds the wait set of
        every entity of every node (milliseconds of Python for a simulator's hundreds), so a turn every tenth of a
        second to look at `stop` cost an idle simulator more than anything it simulated. This thread waits on
        `stop` instead, where a signal handler runs at once (a thread blocked in the middleware's wait runs none
        until it returns), and ends the executor's turn when it is time to end.
        """
        ended = threading.Event()
        failed: list[BaseException] = []
        serving = threading.Thread(target=self._serve, args=(stop, ended, failed), name="tb4-executor", daemon=True)
        serving.start()
        stopping = stop or threading.Event()
        queue_watch = ExecutorQueueWatch(self.executor, self.robot_node.get_logger().warning)
        try:
            while not ended.is_set() and self.context.ok() and self.loop.running:
                if stopping.wait(STOP_LOOK_PERIOD):
                    break
                queue_watch.look()
        finally:
            ended.set()
            self._end_turn.trigger()
            serving.join(timeout=SERVE_END_TIMEOUT)
        if failed:
            raise failed[0]

    def _serve(self, stop: threading.Event | None, ended: threading.Event, failed: list[BaseException]) -> None:
        """The executor's turns until `ended` (see spin); a failure of the context's is handed to spin's thread."""
        logger = self.robot_node.get_logger()
        try:
            while not ended.is_set() and self.context.ok() and not (stop and stop.is_set()):
                try:
                    self.executor.spin_once(timeout_sec=SERVE_TURN_TIMEOUT)
                except ExternalShutdownException:
                    raise
                except Exception as exc:  # a bad message or a bug in one callback must not take the simulator down
                    logger.error(f"callback failed: {type(exc).__name__}: {exc}")
        except BaseException as exc:  # noqa: BLE001 - spin raises it in the thread that called it
            failed.append(exc)
        finally:
            ended.set()

    def stop_publishing(self) -> None:
        """Stop the loop, after which nothing is published, then wait (at most DELIVERY_TIMEOUT) until a recorder
        reading the reliable topics has acknowledged every message: the last ones are then in its queue before the
        writers go."""
        self.loop.stop()
        self._deliver()

    def _deliver(self) -> None:
        if self.ledger is None or self._delivered:
            return
        self._delivered = True
        late = self.ledger.wait_for_delivery(DELIVERY_TIMEOUT)
        if late:
            self.robot_node.get_logger().info(  # the recorder says which messages it missed, if any
                f"a recorder had not acknowledged every message of {', '.join(late)} within {DELIVERY_TIMEOUT:g} s"
            )

    def finish_run(self) -> None:
        """Stop the loop, write the run record, and wait (at most DELIVERY_TIMEOUT) until a recorder has
        acknowledged every message: what the run leaves is complete once this returns. `close` calls it."""
        self.loop.stop()
        if not self._finished:
            self._finished = True
            self.write_record()
        self._deliver()  # after the record: a recorder in another process (tb4 run's) compares with it meanwhile

    def close(self) -> None:
        """Finish the run (`finish_run`), then end the executor and destroy every node."""
        self.finish_run()
        self.executor.shutdown(timeout_sec=2.0)
        for robot in self.robots:
            robot.close()
        for node in self.all_nodes():
            node.destroy_node()

    def _fleet_summary(self) -> dict[str, dict[str, Any]]:
        """Each robot's end state for the run record: bumps reported, docked, battery, where it stands."""
        out = {}
        for robot in self.robots:
            pose = robot.sim.pose()
            out[robot.namespace] = {
                "bumps": robot.create3.bumps,
                "docked": robot.sim.is_docked(),
                "battery": robot.sim.battery().percentage,
                "pose": [pose.x, pose.y, pose.yaw],
            }
        return out

    def summary(self) -> str:
        return (
            f"sim time {self.sim.time:.1f} s, real-time factor {self.loop.real_time_factor:.1f}x, "
            f"bumps {self.create3.bumps}"
        )


def _start_recorder(path: Path, simulator: Simulator) -> Any:
    """Record every robot's topics to MCAP from the start: the ready line comes once the map and the static
    transforms are in the file (or after RECORDER_STARTUP_TIMEOUT, saying which are missing)."""
    from tb4.runner.mcap_record import McapRecorder

    fleet = [robot.namespace for robot in simulator.robots]
    recorder = McapRecorder(path, fleet if simulator.fleet is not None else simulator.namespace, signal_handlers=False)
    missing = recorder.wait_for_startup_topics(RECORDER_STARTUP_TIMEOUT)
    if missing:
        print(f"tb4 sim: recording without {', '.join(missing)} (not received in {RECORDER_STARTUP_TIMEOUT:g} s)")
    return recorder


def _close_recorder(recorder: Any, simulator: Simulator | None) -> None:
    """End the recording once nothing is published any more, checked against what the simulator published: an
    incomplete one is said loudly, and the run record keeps the report."""
    published = first_sent = None
    if simulator is not None:
        simulator.stop_publishing()
        if simulator.ledger is not None:
            published, first_sent = simulator.ledger.snapshot(), simulator.ledger.first_sent()
    report = recorder.close(published, first_sent=first_sent)
    warning = report.warning()
    if warning:
        print(f"tb4 sim: warning: {warning}", file=sys.stderr, flush=True)
    if simulator is not None:
        simulator.recording = report.to_dict()


def _start_foxglove(options: FoxgloveOptions) -> Any:
    """Bind the Foxglove server before the simulator is built: a port in use stops the start, not half of it."""
    from tb4.foxglove.live import FoxgloveLive

    return FoxgloveLive(options.host, options.port, sim_time=True)


def serve_control(simulator: Simulator, stop: threading.Event, lines: Any = None, out: Any = None) -> None:
    """Serve the commands of the program that started this simulator, one JSON line each on `lines` (standard
    input), each answered by a line `CONTROL_REPLY {json}` on `out` (standard output) with its "id":

        {"id": 1, "reset": {"seed": 5, "record_run": "/path/run.json"}}  reset_world: the new run, its record there
        {"id": 2, "write": true}                                          write_record: the run, on disk for good

    A reply holds "ok": true, or "ok": false and "error". The end of the input (the program ended or closed it)
    stops the simulator, as Ctrl-C does.

    Args:
        simulator: the simulator to reset.
        stop: set at the end of the input.
        lines: where the commands come from (default: sys.stdin).
        out: where the replies go (default: sys.stdout).
    """
    import json

    source = lines if lines is not None else sys.stdin
    sink = out if out is not None else sys.stdout
    for line in source:
        if not line.strip():
            continue
        reply: dict[str, Any] = {"ok": True}
        try:
            command = json.loads(line)
            reply["id"] = command.get("id")
            if "reset" in command:
                reset = command["reset"]
                record = reset.get("record_run")
                simulator.reset_world(int(reset["seed"]), Path(record) if record else None)
                reply["seed"] = simulator.seed
            elif command.get("write"):
                written = simulator.write_record(final=True)  # the trial is over: not rewritten at close
                reply["record"] = None if written is None else str(written)
            else:
                raise ValueError(f"unknown command {line.strip()[:200]!r}")
        except (ValueError, KeyError, TypeError, AttributeError, OSError, LoopStopped, TimeoutError) as exc:
            reply.update(ok=False, error=f"{type(exc).__name__}: {exc}")
        print(f"{CONTROL_REPLY} {json.dumps(reply)}", file=sink, flush=True)
    stop.set()


def main(options: SimulatorOptions) -> int:
    """Run the simulator in the foreground until Ctrl-C / SIGTERM."""
    stop = threading.Event()
    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    simulator = None
    viewer = None
    recorder = None
    foxglove = None
    try:
        if options.foxglove is not None:
            foxglove = _start_foxglove(options.foxglove)
        with abandoned_ports_watched():  # the process's DDS participant is made with its first node
            simulator = Simulator(options)
        # the loop starts once the recorder, the viewer and Foxglove see the world: a replay at --rate max could
        # otherwise be over before they had read its first seconds (a recording with no /ground_truth at all)
        if options.record is not None:
            recorder = _start_recorder(options.record, simulator)
        if options.view_port is not None:
            require_extra("viewer")
            from tb4.viewer.launch import start_viewer_in_thread

            viewer = start_viewer_in_thread(namespace=simulator.namespace, port=options.view_port)
            print(f"tb4 viewer: {viewer.url}", flush=True)
        if foxglove is not None:
            foxglove.serve([r.namespace for r in simulator.robots] if simulator.fleet else simulator.namespace)
            print(f"tb4 foxglove: {foxglove.url} (open it in the Foxglove app: Open connection)", flush=True)
        simulator.start()
        rate = "max" if math.isinf(options.rate) else f"{options.rate:g}x"
        print(
            f"{READY_LINE}: world={simulator.world.name} rate={rate} seed={options.seed} "
            f"namespace={simulator.namespace or '/'} localization={options.localization}"
            f"{' robots=' + ','.join(r.namespace for r in simulator.robots) if simulator.fleet else ''}"
            f"{' exact' if options.exact else ''}",
            flush=True,
        )
        if options.control:
            threading.Thread(target=serve_control, args=(simulator, stop), name="tb4-control", daemon=True).start()
        simulator.spin(stop)
        if simulator.loop.error is not None:
            print(f"tb4 sim: the simulation loop failed: {simulator.loop.error!r}", file=sys.stderr)
            return 1
        return 0
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except MissingExtraError as exc:
        print(f"tb4 sim: {exc}", file=sys.stderr)
        return 2
    except FoxgloveError as exc:
        print(f"tb4 sim: --foxglove: {exc}", file=sys.stderr)
        return 2
    finally:
        if viewer is not None:
            viewer.stop()
        if foxglove is not None:
            foxglove.close()
        if recorder is not None:
            _close_recorder(recorder, simulator)  # before the simulator's nodes go: their last messages drain
        if simulator is not None:
            print(f"tb4 sim stopped: {simulator.summary()}", flush=True)
            simulator.finish_run()
        # all that is left is ROS's teardown, which must not hold whoever waits for this process for good (a
        # simulator stopped by tb4 run once waited in it until killed, its run finished)
        exit_within(TEARDOWN_TIMEOUT)
        if simulator is not None:
            simulator.close()
        rclpy.try_shutdown()
        time.sleep(0)
