"""The simulator process's heart: one fixed-step loop in sim time running the Simulation and the nav core.

ROS callbacks never touch the simulation directly: they hand a function to `SimLoop.call`, which the loop runs
between two control ticks. That keeps runs deterministic (same seed and inputs on the same ticks, same trajectory)
and lets the loop run at real time, N times real time, or as fast as the CPU allows (while a robot acts: a waiting
simulator runs at WAITING_RATE). No rclpy here.

Every change a request makes to the world goes through `inputs` (`view.inputs.nav.start_spin(...)`): a named core
call with plain arguments that the loop writes down, with its tick, in the run's InputJournal when one is kept, so
`tb4 replay` can re-run the world without DDS. A function handed to `call` may read the world freely but changes it
only through `inputs`; a change that cannot be journaled goes through `call_outside_replay`, which says so in the
journal (the replay then names it instead of silently differing).
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from functools import partial
from typing import Any, Protocol, TypeVar

from tb4.nav.docking import DockingServerCore
from tb4.nav.server import NavigationCore
from tb4.replay.journal import INPUTS, InputJournal
from tb4.ros.handoff import Handoff
from tb4.sim.fleet import Fleet
from tb4.sim.simulation import Simulation

__all__ = [
    "SimLoop",
    "RobotLoop",
    "LoopView",
    "Inputs",
    "Stepper",
    "LoopStopped",
    "task_done",
    "IDLE_TICK_LIMIT",
    "WAITING_RATE",
]

#: sim s: the most one tick covers at --rate max while a robot rests on its dock and nothing can happen but the
#: clock and the battery (a script waiting for it to charge, for hours of sim time). Clients at --rate max already
#: saw /clock advance by about this much between two of its messages (it goes out at most 250 times a wall second).
IDLE_TICK_LIMIT = 1.0

#: times real time: the pace at --rate max while every robot waits for a command (`SimLoop.waiting`). Unbounded, an
#: idle simulator takes a whole core to run thousands of times real time for nobody, on the dock or off it; at 100x
#: it takes a small fraction of one, and a script's pause of a few milliseconds between two commands costs seconds
#: of sim time, not minutes. A charge on the dock is no wait: it keeps the fast-forward.
WAITING_RATE = 100.0


def task_done(task: Any) -> bool:
    done = task.done  # a property on nav tasks, a method on the dock state
    return bool(done() if callable(done) else done)


T = TypeVar("T")


class Stepper(Protocol):
    """What the loop steps: one Simulation, or a tb4.sim.fleet.Fleet of them (one clock)."""

    @property
    def time(self) -> float: ...

    def step(self, n: int = 1) -> None: ...


class LoopStopped(RuntimeError):
    """The loop is not running (shutting down), so the request cannot be served."""


@dataclass
class _Periodic:
    period: float
    callback: Callable[[float], None]
    next_time: float = 0.0


class SimLoop:
    """Steps physics at `sim.physics_dt` and the nav core every `control_period` of sim time, paced by `rate`.

    A fleet passes `world` (stepping every robot's Simulation together) and `navs` (every robot's nav core, stepped
    in order after physics); `sim` and `nav` are then the first robot's, and robot(k) is robot k's view."""

    def __init__(
        self,
        sim: Simulation,
        nav: NavigationCore,
        rate: float = 1.0,
        control_period: float = 0.05,
        hold: bool = False,
        world: Stepper | None = None,
        navs: list[NavigationCore] | None = None,
    ) -> None:
        if not (rate > 0):
            raise ValueError(f"rate must be positive (or inf for as fast as possible), got {rate}")
        self.sim = sim
        self.nav = nav
        self.world: Stepper = world if world is not None else sim
        self.navs = navs if navs is not None else [nav]
        self.robots: list[Simulation] = list(self.world) if isinstance(self.world, Fleet) else [sim]
        self.rate = rate
        self.control_period = control_period
        self.steps_per_tick = max(1, round(control_period / sim.physics_dt))
        self.lock = threading.RLock()  # held while the world changes; readers on other threads take it too
        self._requests = Handoff(lambda: LoopStopped("the simulator is shutting down"))
        self._periodic: list[_Periodic] = []
        self._tick_listeners: list[Callable[[float], None]] = []
        self._busy_checks: list[Callable[[], bool]] = []
        self._watched: list[tuple[Any, threading.Event]] = []
        self._watch_lock = threading.Lock()
        self._ticks = 0
        self.publish_errors = 0
        self._last_error_report = -math.inf
        self.report: Callable[[str], None] = lambda text: print(f"tb4 sim: {text}", file=sys.stderr, flush=True)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.real_time_factor = 0.0
        self.error: BaseException | None = None
        # While held, time runs at real time: a mission script starting up (imports, discovery, its initial pose and
        # waitUntilNav2Active) does not burn minutes of sim time on the dock. The first command that makes the robot
        # act (an action goal, a Create 3 service, a global localization) releases the hold.
        self._held = hold
        # the inputs of the run, when it is recorded (tb4 replay); set before start()
        self.journal: InputJournal | None = None
        self._fast_forward = False  # the last tick's mode, as the journal has it
        # a recorded run's inputs, applied each on its tick (tb4.replay.engine.ReplayFeed): the loop replays it and
        # stops after its last tick
        self.feed: Any = None
        self._inputs = [Inputs(self, k) for k in range(len(self.robots))]
        # each robot's Nav2 docking_server (its tasks are stepped with the world: a replay steps them the same way)
        self.dockings = [DockingServerCore(robot, nav) for robot, nav in zip(self.robots, self.navs, strict=True)]
        self._hold_at_start = hold
        self._reset_listeners: list[Callable[[], None]] = []

    # --- wiring ------------------------------------------------------------------------------------------
    def every(self, period: float, callback: Callable[[float], None]) -> None:
        """Call `callback(now)` every `period` sim seconds (from the loop thread)."""
        self._periodic.append(_Periodic(period, callback, self.sim.time))

    def on_tick(self, callback: Callable[[float], None]) -> None:
        self._tick_listeners.append(callback)

    def busy_while(self, check: Callable[[], bool]) -> None:
        """`check()` true: something outside the nav core (a side task) must be stepped every control period, so
        the loop does not take idle ticks together (see `idle_periods`)."""
        self._busy_checks.append(check)

    def watch(self, task: Any) -> threading.Event:
        """An event the loop sets when `task` is done (checked after every tick), or when the loop stops."""
        event = threading.Event()
        with self._watch_lock:
            self._watched.append((task, event))
        if task_done(task) or self._stop.is_set():
            event.set()
        return event

    def _notify_watchers(self, stopping: bool = False) -> None:
        with self._watch_lock:
            if not self._watched:
                return
            keep = []
            for task, event in self._watched:
                if stopping or task_done(task):
                    event.set()
                else:
                    keep.append((task, event))
            self._watched = keep

    # --- world reset ----------------------------------------------------------------------------------------
    def on_reset(self, callback: Callable[[], None]) -> None:
        """Call `callback()` (in the loop thread) after each `reset`: state kept beside the world (a publisher's
        last stamp, a counter) goes back to its start."""
        self._reset_listeners.append(callback)

    def reset(self, seed: int) -> None:
        """Back to the world as built, with `seed` (tb4.sim.Simulation.reset and tb4.nav NavigationCore.reset):
        every running task and goal is canceled (a client waiting on one gets its end), the clock goes back to 0,
        the timers start again from 0 and the start-up hold is on again as at the start. Runs in the loop thread
        (between two ticks, through `call`); one robot only.

        Args:
            seed: the new run's seed.

        Raises:
            ValueError: the loop steps a fleet.
        """
        if self.world is not self.sim:
            raise ValueError("a fleet's world cannot be reset: start a new simulator")
        self.call(lambda: self._reset(seed))

    def _reset(self, seed: int) -> None:
        with self.lock:
            with self._watch_lock:
                watched = [task for task, _event in self._watched if not task_done(task)]
            for task in watched:  # an action goal's task (the nav core's, a dock's, a drive goal's) ends canceled
                task.cancel()
            self.sim.reset(seed)
            self.nav.reset(seed)
            for docking in self.dockings:
                docking.reset()
            self._held = self._hold_at_start
            # a new run: its journal starts at tick 0 with the new seed (a journal is one run's, as its record)
            self._ticks = 0
            self._fast_forward = False
            if self.journal is not None:
                self.journal = InputJournal({**self.journal.settings, "seed": seed})
            for job in self._periodic:
                job.next_time = self.sim.time
        self._notify_watchers(stopping=True)
        for listener in self._reset_listeners:
            listener()

    # --- requests from other threads ----------------------------------------------------------------------
    def submit(self, fn: Callable[[], T]) -> Future:
        return self._requests.submit(fn)

    def call(self, fn: Callable[[], T], timeout: float = 10.0) -> T:
        """Run `fn` in the loop thread and return its result (re-raising its exception). `fn` reads the world as it
        likes; it changes it only through `inputs` (see the module's docstring)."""
        if self._thread is None or threading.current_thread() is self._thread:
            return fn()
        return self.submit(fn).result(timeout=timeout)

    def call_outside_replay(self, fn: Callable[[], T], what: str, moves: bool = True, timeout: float = 10.0) -> T:
        """`call` for a change of the world that is no journaled input. The journal notes `what`: with `moves`,
        as a change replay cannot redo (the run is then not reproducible); without, as one that cannot change
        any robot's motion (a light ring, a sound), which replay leaves out."""
        if self.journal is not None:
            self.journal.untrack(what, moves)
        return self.call(fn, timeout)

    @property
    def inputs(self) -> Inputs:
        """The first robot's inputs (a fleet's others: RobotLoop.inputs)."""
        return self._inputs[0]

    def robot_inputs(self, robot: int) -> Inputs:
        return self._inputs[robot]

    def apply(self, robot: int, target: str, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]) -> Any:
        """Apply one input in the loop thread (waiting for it when called from another), journaled first."""

        def run() -> Any:
            obj = self._target(robot, target)
            if self.journal is not None:
                self.journal.add(self._ticks, robot, target, method, args, kwargs)
            result = getattr(obj, method)(*args, **kwargs)
            if self.journal is not None:
                self.journal.tasks.started(result)
            return result

        return self.call(run)

    def cancel(self, robot: int, task: Any) -> None:
        """Cancel a running task between two ticks (without waiting); journaled when an input started it."""

        self.submit(lambda: self.cancel_now(robot, task))

    def cancel_now(self, robot: int, task: Any) -> None:
        """`cancel` in the loop thread."""
        if self.journal is not None and not self.journal.add_task_call(self._ticks, robot, task, "cancel"):
            self.journal.untrack("a cancel of a task no journaled input started")
        task.cancel()

    def _target(self, robot: int, target: str) -> Any:
        sim = self.robots[robot]
        if target == "docking":
            return self.dockings[robot]
        return {"sim": sim, "nav": self.navs[robot], "base": sim.base}[target]

    # --- running ------------------------------------------------------------------------------------------
    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="sim-loop", daemon=True)
        self._thread.start()

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        self._drain(LoopStopped("the simulator stopped"))
        self._notify_watchers(stopping=True)

    def release(self) -> None:
        """End the start-up hold: from now on the loop runs at its configured rate."""
        self._held = False

    @property
    def held(self) -> bool:
        return self._held

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def tick(self, fast_forward: bool = False) -> None:
        """One control period: serve queued requests, step physics, step navigation, run due publishers.
        `fast_forward`: while the world is idle, up to IDLE_TICK_LIMIT at once (`idle_periods`)."""
        self._ticks += 1
        if self.feed is not None:
            fast_forward = self.feed.before_tick(self, self._ticks)
        journal = self.journal
        if journal is not None and fast_forward != self._fast_forward:
            journal.add(self._ticks, 0, "loop", "fast_forward", (fast_forward,), {})
        self._fast_forward = fast_forward
        self._serve_requests()
        with self.lock:
            self.step_world(fast_forward)
            now = self.sim.time
            if journal is not None:
                journal.after_tick(self._ticks, now, tuple((r.x, r.y, r.yaw) for r in self.robots))
        self._notify_watchers()
        for listener in self._tick_listeners:
            self._guarded(listener, now)
        for job in self._periodic:
            if now + 1e-9 >= job.next_time:
                job.next_time = max(job.next_time + job.period, now)
                self._guarded(job.callback, now)

    def step_world(self, fast_forward: bool) -> None:
        """The world's part of a tick: physics for one control period (or an idle span), then every nav core."""
        periods = self.idle_periods() if fast_forward else 1
        self.world.step(self.steps_per_tick * periods)
        now = self.sim.time
        for nav in self.navs:
            nav.step(now)
        for docking in self.dockings:
            docking.step(now)

    @property
    def ticks(self) -> int:
        """Ticks taken so far (the journal's clock)."""
        return self._ticks

    def idle_periods(self) -> int:
        """How many control periods the next tick may take together (1: just one). More than one only for a robot
        resting on its dock, where a mission script waits for the battery to charge (hours of sim time), and only
        while nothing but the clock and the battery can change: one robot (a fleet's robots meet each other), no
        motion task, no side task, and the robot at rest for the whole span (no command, action, timed input or
        moving obstacle near: `Simulation.still_steps`), whose steps it then takes together with the same result
        to the last bit. The nav core and the publishers run once for the span: a tick costs about the same
        whatever it covers, so the charge no longer takes 20 ticks per sim second. Requests are served before the
        span; one arriving during it waits for its end (a fraction of a millisecond). Away from the dock a robot
        standing still between two commands of a script keeps the usual ticks: fast-forwarding there would put
        minutes of sim time between a script's commands."""
        if self.world is not self.sim or self.nav.active or self._side_busy():
            return 1
        if not self.sim.is_docked():
            return 1
        most = max(1, int(IDLE_TICK_LIMIT / self.control_period + 1e-9))
        return max(1, self.sim.still_steps(most * self.steps_per_tick) // self.steps_per_tick)

    def waiting(self) -> bool:
        """Whether every robot waits for a command: no motion task or side task runs, and each robot rests with
        nothing driving it and no charge under way (`Simulation.resting`). Only the clock and a resting battery's
        drain change then, so at --rate max the loop runs at WAITING_RATE instead of taking a core."""
        if any(nav.active for nav in self.navs) or self._side_busy():
            return False
        return all(robot.resting() for robot in self.robots)

    def _side_busy(self) -> bool:
        """Something beside the nav cores runs and must be stepped every control period."""
        return any(d.busy for d in self.dockings) or any(busy() for busy in self._busy_checks)

    @property
    def docking(self) -> DockingServerCore:
        """The first robot's docking server (a fleet's others: RobotLoop.docking)."""
        return self.dockings[0]

    def pace(self) -> float:
        """The loop's speed now, in times real time (inf: as fast as the CPU allows): real time while held,
        WAITING_RATE at --rate max while every robot waits (`waiting`), else the configured rate."""
        if self._held:
            return 1.0
        if math.isinf(self.rate) and self.waiting():
            return WAITING_RATE
        return self.rate

    def _guarded(self, callback: Callable[[float], None], now: float) -> None:
        """Publishers run here: a failed publish (DDS out of resources, a reader vanishing) is reported and the
        simulation goes on; it must never end the run."""
        try:
            callback(now)
        except Exception as exc:
            self.publish_errors += 1
            wall = time.monotonic()
            if wall - self._last_error_report >= 1.0:
                self._last_error_report = wall
                self.report(f"{getattr(callback, '__name__', 'callback')} failed ({self.publish_errors} so far): {exc}")

    def _serve_requests(self) -> None:
        self._requests.run_pending(guard=self.lock)

    def _drain(self, exc: BaseException) -> None:
        self._requests.close(exc)

    def _run(self) -> None:
        wall0, sim0 = time.monotonic(), self.sim.time
        window_wall, window_sim = wall0, sim0
        try:
            rate = self.pace()
            while not self._stop.is_set():
                if self.feed is not None and self.feed.finished(self._ticks + 1):
                    break  # the replayed run ended here
                self.tick(fast_forward=not self._held and math.isinf(self.rate))
                wall = time.monotonic()
                if rate != (pace := self.pace()):  # released, waiting or no longer: pace from here
                    rate, wall0, sim0 = pace, wall, self.sim.time
                if math.isfinite(rate):
                    target = wall0 + (self.sim.time - sim0) / rate
                    if target - wall > 0:
                        time.sleep(target - wall)
                    elif wall - target > 0.5:  # fell behind (slow machine): do not try to catch up in a burst
                        wall0, sim0 = wall, self.sim.time
                elif self._ticks % 20 == 0:
                    time.sleep(0)  # now and then, hand the GIL to the ROS threads at once
                if wall - window_wall >= 1.0:
                    self.real_time_factor = (self.sim.time - window_sim) / (wall - window_wall)
                    window_wall, window_sim = wall, self.sim.time
        except BaseException as exc:
            self.error = exc
            raise
        finally:
            self._stop.set()
            self._drain(LoopStopped("the simulator loop ended"))
            self._notify_watchers(stopping=True)


class LoopView(Protocol):
    """What the ROS interfaces of one robot use of the loop: that robot's sim and nav core, and the shared
    loop's requests, timers and lock (SimLoop for a single robot, RobotLoop for one robot of a fleet)."""

    sim: Simulation
    nav: NavigationCore
    lock: Any

    def every(self, period: float, callback: Callable[[float], None]) -> None: ...
    def on_tick(self, callback: Callable[[float], None]) -> None: ...
    def busy_while(self, check: Callable[[], bool]) -> None: ...
    def on_reset(self, callback: Callable[[], None]) -> None: ...
    def watch(self, task: Any) -> threading.Event: ...
    def submit(self, fn: Callable[[], T]) -> Future: ...
    def call(self, fn: Callable[[], T], timeout: float = 10.0) -> T: ...
    def call_outside_replay(self, fn: Callable[[], T], what: str, moves: bool = True, timeout: float = 10.0) -> T: ...
    def release(self) -> None: ...

    @property
    def inputs(self) -> Inputs: ...

    @property
    def docking(self) -> DockingServerCore: ...

    @property
    def held(self) -> bool: ...

    @property
    def running(self) -> bool: ...


class RobotLoop:
    """One robot of a fleet as its interfaces see the loop: its own sim and nav core; requests, timers, the lock
    and the clock are the one shared loop's, so every robot's callbacks run in the same loop thread."""

    def __init__(self, loop: SimLoop, sim: Simulation, nav: NavigationCore) -> None:
        self.loop = loop
        self.sim = sim
        self.nav = nav
        self.lock = loop.lock
        index = loop.robots.index(sim)
        self.inputs = loop.robot_inputs(index)
        self.docking = loop.dockings[index]

    def every(self, period: float, callback: Callable[[float], None]) -> None:
        self.loop.every(period, callback)

    def on_tick(self, callback: Callable[[float], None]) -> None:
        self.loop.on_tick(callback)

    def busy_while(self, check: Callable[[], bool]) -> None:
        self.loop.busy_while(check)

    def on_reset(self, callback: Callable[[], None]) -> None:
        self.loop.on_reset(callback)

    def watch(self, task: Any) -> threading.Event:
        return self.loop.watch(task)

    def submit(self, fn: Callable[[], T]) -> Future:
        return self.loop.submit(fn)

    def call(self, fn: Callable[[], T], timeout: float = 10.0) -> T:
        return self.loop.call(fn, timeout)

    def call_outside_replay(self, fn: Callable[[], T], what: str, moves: bool = True, timeout: float = 10.0) -> T:
        return self.loop.call_outside_replay(fn, what, moves, timeout)

    def release(self) -> None:
        self.loop.release()

    @property
    def held(self) -> bool:
        return self.loop.held

    @property
    def running(self) -> bool:
        return self.loop.running


class Inputs:
    """One robot's journaled inputs: `inputs.nav.start_spin(1.57, 10.0, False)` runs the nav core's start_spin in
    the loop thread (waiting for it from another thread) and, when the run keeps a journal, writes it down first.
    Only the methods tb4.replay.journal.INPUTS names exist here."""

    def __init__(self, loop: SimLoop, robot: int) -> None:
        self._loop = loop
        self.robot = robot
        self.sim = _InputTarget(self, "sim")
        self.nav = _InputTarget(self, "nav")
        self.base = _InputTarget(self, "base")
        self.docking = _InputTarget(self, "docking")

    def apply(self, target: str, method: str, *args: Any, **kwargs: Any) -> Any:
        return self._loop.apply(self.robot, target, method, args, kwargs)

    def cancel(self, task: Any) -> None:
        """Cancel `task` between two ticks, without waiting."""
        self._loop.cancel(self.robot, task)


class _InputTarget:
    def __init__(self, inputs: Inputs, target: str) -> None:
        self._inputs = inputs
        self._target = target

    def __getattr__(self, method: str) -> Callable[..., Any]:
        if method.startswith("_") or method not in INPUTS[self._target]:
            raise AttributeError(f"{self._target}.{method} is not a journaled input (tb4.replay.journal.INPUTS)")
        return partial(self._inputs.apply, self._target, method)
