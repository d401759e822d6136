"""Running one mission (a tutorial, or a user's script or module) in the built-in simulator: start the simulator,
run the mission against it over DDS, show progress, stop the simulator, draw the picture, and say plainly how it
went."""

from __future__ import annotations

import contextlib
import json
import os
import re
import selectors
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from tb4.core.waits import Deadline, wait_until
from tb4.extras import MissingExtraError, require_extra
from tb4.foxglove import FoxgloveError, FoxgloveOptions
from tb4.processes import (
    READY_LINE,
    ManagedProcess,
    claim_domain_id,
    remove_stale_shm,
    ros_environment,
    shm_snapshot,
    tb4_command,
)
from tb4.rosenv import require_ros
from tb4.runner.display import Display
from tb4.runner.missions import Mission
from tb4.runner.tutorial_start import StartGate

if TYPE_CHECKING:
    from tb4.sim.world import World

__all__ = [
    "RunOptions",
    "RunOutcome",
    "run_mission",
    "mission_environment",
    "mission_reason",
    "finish_record",
    "end_mission_process",
    "MISSION_STOP_GRACE",
    "TIMED_OUT",
]

SIM_START_TIMEOUT = 60.0
SIM_STOP_TIMEOUT = 20.0  # wall seconds for the simulator to write its record and end after Ctrl-C
RECORDER_STARTUP_TIMEOUT = 10.0  # wall seconds for the latched map and static transforms to reach the recorder
MONITOR_MATCH_TIMEOUT = 10.0  # wall seconds for the monitor to match the simulator (RunMonitor.wait_for_publishers)
TIMED_OUT = 124  # the exit code of a mission ended at its time limit (as `timeout` uses)
MISSION_STOP_GRACE = 5.0  # wall seconds a mission gets to end after Ctrl-C (its goal canceled) before SIGTERM


@dataclass
class RunOptions:
    world: str | None = None
    rate: str = "max"
    seed: int = 0
    battery: float | None = None
    namespace: str = ""
    output_dir: Path = Path("runs")
    mode: str = "live"  # live | plain | json | quiet
    record: Path | None = None
    view: bool = False
    view_port: int = 8765
    attach: bool = False  # run against a simulator/robot that is already up
    tutorial_args: list[str] = field(default_factory=list)
    exact: bool = False  # tb4 sim --exact: no odometry drift, no lidar noise
    localization: str = "amcl"  # tb4 sim --localization
    # /dev/shm before this process's DDS participants (tb4.processes.shm_snapshot); taken here when None
    shm_before: set[str] | None = None
    time_limit: float | None = None  # wall seconds the mission may run; then it is ended and the run timed out
    fail_on_bump: bool = False  # a run whose robot bumped into anything fails, whatever the mission's exit code
    picture: bool = True  # draw run.png (a sweep draws only its failures')
    foxglove: FoxgloveOptions | None = None  # serve the run's topics to the Foxglove app


@dataclass
class RunOutcome:
    """How a run went: the exit code (the mission's own, or ours), why in words, and what it left behind."""

    exit_code: int
    reason: str
    run_dir: Path
    picture: Path | None = None
    record: Path | None = None
    mcap: Path | None = None
    bumps: list[dict[str, Any]] = field(default_factory=list)  # every robot's bumps: {"t", "x", "y", "robot"}
    wall_time: float | None = None  # s from the gate's opening to the mission's end
    recording: dict[str, Any] | None = None  # what the MCAP recording holds and missed (RecordingReport.to_dict)


def _run_dir(base: Path, name: str) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    path = base / f"{name}-{stamp}"
    n = 1
    while path.exists():
        n += 1
        path = base / f"{name}-{stamp}-{n}"
    path.mkdir(parents=True)
    return path


def _last_error(lines: list[str]) -> str | None:
    """The line that best says why a mission failed: the exception a traceback ends with, else the last error."""
    for k in range(len(lines) - 1, -1, -1):
        line = lines[k]
        if line.startswith("Traceback"):
            rest = [text.strip() for text in lines[k + 1 :] if text.strip() and not text.startswith(" ")]
            return rest[0] if rest else line.strip()
        if "[ERROR]" in line or line.startswith(("tb4:", "Error")):
            return line.strip()
    return None


def run_mission(mission: Mission, options: RunOptions) -> RunOutcome:
    """Run `mission` in a simulator of its own (or, with `options.attach`, against whatever runs).

    Args:
        mission: what to run (tb4.runner.missions.resolve_mission).
        options: the simulator's settings, the display mode, the recording, the time limit.

    Returns:
        The RunOutcome: the mission's exit code (TIMED_OUT at the time limit, 130 when interrupted), a reason in
        words, and the run folder with its picture, record and recording.
    """
    world = options.world or mission.world
    run_dir = _run_dir(options.output_dir, mission.name)
    if mission.robots and options.namespace:
        reason = f"{mission.name} runs a fleet (/robot1../robot{mission.robots}): --namespace does not apply"
        return RunOutcome(2, reason, run_dir)
    watched = options.namespace or ("/robot1" if mission.robots else "")  # the robot the display follows
    env = mission_environment(
        int(os.environ["ROS_DOMAIN_ID"]) if "ROS_DOMAIN_ID" in os.environ else claim_domain_id(), world
    )
    os.environ["ROS_DOMAIN_ID"] = env["ROS_DOMAIN_ID"]
    display = Display(options.mode, waypoints_total=mission.waypoints)
    shm_before = options.shm_before if options.shm_before is not None else shm_snapshot()
    record_path = run_dir / "run.json"
    sim: ManagedProcess | None = None
    gate: StartGate | None = None
    proc: subprocess.Popen[bytes] | None = None
    picture: Path | None = None
    picture_world: World | None = None
    monitor = recorder = viewer = foxglove = None
    recording: dict[str, Any] | None = None
    output_lines: list[str] = []
    deadline: Deadline | None = None
    wall_time: float | None = None
    interrupted = False  # Ctrl-C or SIGTERM (which tb4 run turns into one)
    try:
        if options.foxglove is not None:  # before the simulator: a port in use stops the run before anything starts
            try:
                foxglove = _start_foxglove(options, display)
            except (FoxgloveError, MissingExtraError) as exc:
                return RunOutcome(2, f"--foxglove: {exc}", run_dir)
        if not options.attach:
            sim_args = tb4_command(
                "sim",
                "--world",
                world,
                "--rate",
                options.rate,
                "--seed",
                str(options.seed),
                "--record-run",
                str(record_path),
                "--hold",  # real time until the tutorial's first command: start-up costs no sim time
                "--localization",
                options.localization,
            )
            if options.exact:
                sim_args.append("--exact")
            if options.namespace:
                sim_args += ["--namespace", options.namespace]
            if mission.robots:
                sim_args += ["--robots", str(mission.robots)]
            if options.battery is not None:
                sim_args += ["--battery", str(options.battery)]
            display.message(f"tb4 run {mission.name}: starting the simulator (world {world}, rate {options.rate})")
            sim = ManagedProcess(sim_args, env=env, log_path=run_dir / "sim.log")
        # while the simulator boots (seconds, one core): the tutorial's imports (it waits at the start gate), the
        # monitor's imports and node, and the picture's imports, instead of after it (the monitor only listens; the
        # hold keeps sim time)
        gate = StartGate()
        proc = _start_tutorial_process(mission, options, env, gate)
        require_ros()  # here, not before the simulator's start: its imports overlap the boot too
        monitor = _start_monitor(watched)
        picture_world = _prepare_picture(world) if options.picture else None
        if sim is not None and not sim.wait_for_output(READY_LINE, SIM_START_TIMEOUT):
            tail = sim.output().strip().splitlines()[-3:]
            return RunOutcome(1, "the simulator did not start: " + " / ".join(tail), run_dir)
        if options.record is not None:
            from tb4.runner.mcap_record import McapRecorder

            fleet = [f"/robot{k + 1}" for k in range(mission.robots)]
            recorder = McapRecorder(options.record, fleet or watched)  # a fleet: every robot's topics
            # the simulator holds time until the first command: waiting here costs no sim time
            missing = recorder.wait_for_startup_topics(RECORDER_STARTUP_TIMEOUT)
            if missing:
                display.message(
                    f"tb4 run: recording without {', '.join(missing)} (not received within "
                    f"{RECORDER_STARTUP_TIMEOUT:g} s)"
                )
        if foxglove is not None:
            foxglove.serve([f"/robot{k + 1}" for k in range(mission.robots)] or watched)
            display.message(f"foxglove: {foxglove.url}")
        if options.view:
            try:
                viewer = _start_viewer(options, display, watched)
            except MissingExtraError as exc:
                display.message(f"tb4 run: no viewer: {exc}")
        if not monitor.wait_for_publishers(MONITOR_MATCH_TIMEOUT):
            display.message(
                "tb4 run: progress may be missing (the simulator's action servers and bumper were not all found "
                f"within {MONITOR_MATCH_TIMEOUT:g} s)"
            )
        display.event(
            {
                "event": "start",
                "tutorial": mission.name,
                "mission": {"name": mission.name, "kind": mission.kind, "target": mission.target},
                "world": world,
                "run_dir": str(run_dir),
            }
        )
        display.start()
        monitor.mission_starts(options.attach)
        gate.open()
        deadline = Deadline(options.time_limit) if options.time_limit is not None else None
        started = time.monotonic()
        code = _follow_tutorial_process(proc, mission, display, monitor, output_lines, deadline)
        wall_time = time.monotonic() - started
    except KeyboardInterrupt:
        code = 130
        interrupted = True
    finally:
        if gate is not None:
            gate.close()  # a tutorial still at the gate ends without running
        if proc is not None:
            end_mission_process(proc)
        if sim is not None:
            sim.interrupt()  # its shutdown runs beside ours and the picture's drawing
        display.stop()
        if monitor is not None:
            monitor.close()
        if viewer is not None:
            viewer.stop()
        if foxglove is not None:
            foxglove.close()
        stopping = Deadline(SIM_STOP_TIMEOUT)
        if sim is not None:
            # the simulator writes the record (all at once, with what it published) first on its way out, then
            # holds its writers until the recorder has acknowledged their last messages: draw meanwhile
            wait_until(lambda: record_path.exists() or not sim.alive(), stopping.remaining())
        if recorder is not None:
            recording = _close_recorder(recorder, record_path if sim is not None else None, display)
        if sim is not None:
            if record_path.exists() and options.picture and not interrupted:
                picture = _draw(picture_world, world, mission.name, record_path, run_dir / "run.png")
            elif interrupted and record_path.exists():
                # stopped by Ctrl-C or SIGTERM, which must end the run within 2 s: drawing takes up to seconds
                print(f"tb4 run: stopped: no picture drawn (tb4 render {run_dir} draws it)", file=sys.stderr)
            sim.stop(timeout=max(stopping.remaining(), 1.0))
        remove_stale_shm(shm_before)

    outcome = RunOutcome(
        code,
        "",
        run_dir,
        picture=picture,
        record=record_path if record_path.exists() else None,
        mcap=options.record if options.record and options.record.exists() else None,
        wall_time=wall_time,
        recording=recording,
    )
    timed_out = code == TIMED_OUT and deadline is not None and deadline.expired
    outcome.reason = mission_reason(code, mission, output_lines, options.time_limit if timed_out else None)
    if sim is not None and sim.popen.returncode not in (0, None, -2, 130) and code == 0:
        outcome.exit_code, outcome.reason = 1, simulator_failure(run_dir / "sim.log")
    if outcome.record is not None:
        finish_record(outcome, mission, options, world)
    return outcome


def mission_environment(domain: int, world: str) -> dict[str, str]:
    """The environment a mission's process runs in: the DDS domain on loopback, the world it runs in, and ROS log
    lines in the plain form `mission_reason` reads errors from.

    Args:
        domain: its ROS_DOMAIN_ID.
        world: the world's name (tutorials that use the world's data, named destinations, read it from TB4_WORLD).

    Returns:
        The environment.
    """
    env = ros_environment(domain)
    env["TB4_WORLD"] = world
    env.setdefault("RCUTILS_COLORIZED_OUTPUT", "0")
    env.setdefault("RCUTILS_CONSOLE_OUTPUT_FORMAT", "[{severity}] [{name}]: {message}")
    return env


def mission_reason(code: int, mission: Mission, output_lines: list[str], time_limit: float | None = None) -> str:
    """Why a mission ended as it did, in words.

    Args:
        code: its exit code.
        mission: what ran.
        output_lines: what it printed.
        time_limit: the limit it was ended at (None: it was not ended at a time limit).

    Returns:
        "succeeded", "interrupted by the user", the time limit, or its last error with its exit code.
    """
    if code == 0:
        return "succeeded"
    if code == 130:
        return "interrupted by the user"
    if code == TIMED_OUT and time_limit is not None:
        return f"timed out: still running after {time_limit:g} s (--time-limit); it was ended"
    reason = _last_error(output_lines) or f"the {mission.kind} exited with code {code}"
    if code not in (0, 130, TIMED_OUT) and not reason.startswith("the "):
        reason = f"exit code {code}: {reason}"
    return reason


def simulator_failure(log: Path) -> str:
    """Why a run whose mission succeeded failed on its simulator's account, in words: it hung on its way out (its
    run finished, it ended itself at its teardown bound, tb4.processes.exit_within, whose "Timeout" line heads its
    threads' stacks in its log), or it failed.

    Args:
        log: the simulator's log.

    Returns:
        The reason, naming the log.
    """
    with contextlib.suppress(OSError):
        if re.search(r"^Timeout \(\d+:\d\d:\d\d\)!$", log.read_text(errors="replace"), re.MULTILINE):
            return f"the simulator hung on its way out, its run finished, and was ended (its threads' stacks: {log})"
    return f"the simulator failed (see {log})"


def finish_record(outcome: RunOutcome, mission: Mission, options: RunOptions, world: str) -> None:
    """Read a finished run's bumps from its record (with `fail_on_bump`, a bump fails the run) and write how the
    run was started and ended into the record (`run`).

    Args:
        outcome: the run's outcome, with its record; its bumps, exit code and reason are set here.
        mission: what ran.
        options: how it ran.
        world: the world it ran in.
    """
    assert outcome.record is not None
    outcome.bumps = _bumps_of(outcome.record)
    if options.fail_on_bump and outcome.bumps and outcome.exit_code == 0:
        first = outcome.bumps[0]
        outcome.exit_code = 1
        outcome.reason = (
            f"bumped {len(outcome.bumps)} time(s) (--fail-on-bump); the first at ({first['x']:.2f}, "
            f"{first['y']:.2f}), sim time {first['t']:.1f} s{' by ' + first['robot'] if first['robot'] else ''}"
        )
    _annotate_record(outcome.record, mission, options, world, outcome)


def _bumps_of(record_path: Path) -> list[dict[str, Any]]:
    """Every robot's bumps in a run record, in time order."""
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    parts = record.get("robots") or {"": record}
    bumps = [
        {"t": e["t"], "x": e["x"], "y": e["y"], "robot": namespace}
        for namespace, part in parts.items()
        for e in part.get("events", [])
        if e.get("type") == "bump"
    ]
    return sorted(bumps, key=lambda bump: bump["t"])


def _annotate_record(record_path: Path, mission: Mission, options: RunOptions, world: str, outcome: RunOutcome) -> None:
    """Add how the run was started and how it ended to its record (`run`), so the run folder alone says what ran,
    with what settings, and the verdict: what `tb4 render`, a test and a sweep read back."""
    from tb4.ros.run_record import write_run_section

    run = {
        "mission": {"name": mission.name, "kind": mission.kind, "target": mission.target},
        "arguments": list(options.tutorial_args),
        "world": world,
        "seed": options.seed,
        "rate": options.rate,
        "battery": options.battery,
        "exact": options.exact,
        "localization": options.localization,
        "robots": mission.robots,
        "namespace": options.namespace,
        "exit_code": outcome.exit_code,
        "reason": outcome.reason,
        "wall_time": None if outcome.wall_time is None else round(outcome.wall_time, 3),
        "bumps": len(outcome.bumps),
    }
    # the recording's check sits beside the simulator's counts it was made against
    extra = {"recording": outcome.recording} if outcome.recording is not None else None
    with contextlib.suppress(OSError, ValueError):
        write_run_section(record_path, run, extra)


def _close_recorder(recorder: Any, record_path: Path | None, display: Display) -> dict[str, Any]:
    """End the recording, checked against what the simulator published (the counts in its run record, written
    once nothing more is published); an incomplete one is said in every mode."""
    from tb4.runner.mcap_record import ledger_in_record

    published, first_sent = ledger_in_record(record_path) if record_path is not None else (None, None)
    report = recorder.close(published, first_sent=first_sent)
    warning = report.warning()
    if warning and display.mode == "quiet":
        print(f"tb4 run: warning: {warning}", file=sys.stderr, flush=True)
    elif warning:
        display.message(f"tb4 run: warning: {warning}")
    return dict(report.to_dict())


def _start_monitor(namespace: str) -> Any:
    from tb4.runner.monitor import RunMonitor

    return RunMonitor(namespace)


def _start_viewer(options: RunOptions, display: Display, namespace: str) -> Any:
    """The viewer shows the world the simulator announces (with --attach: whatever runs, a real robot too)."""
    require_extra("viewer")
    from tb4.viewer.launch import start_viewer_in_thread

    viewer = start_viewer_in_thread(namespace=namespace, port=options.view_port)
    display.message(f"viewer: {viewer.url}")
    return viewer


def _start_foxglove(options: RunOptions, display: Display) -> Any:
    """The Foxglove server, bound before the simulator starts; it is fed once the simulator is ready. A simulator
    publishes /clock, so its messages go out at sim time; a robot reached with --attach may not: wall time."""
    from tb4.foxglove.live import FoxgloveLive

    assert options.foxglove is not None
    return FoxgloveLive(
        options.foxglove.host, options.foxglove.port, sim_time=not options.attach, report=display.message
    )


def _prepare_picture(world_name: str) -> World | None:
    """While the simulator boots: import what _draw needs (matplotlib: a few tenths of a second) and load the
    world it draws on, instead of after the run. None without the render extra (_draw then says so at the end) or
    when the world does not load (the simulator reports that)."""
    try:
        require_extra("render")
        import tb4.runner.picture  # noqa: F401
        from tb4.sim.world import load_world

        return load_world(world_name)
    except (MissingExtraError, OSError, ValueError):
        return None


def _draw(world: World | None, world_name: str, tutorial: str, record_path: Path, output: Path) -> Path | None:
    try:
        require_extra("render")
        from tb4.runner.picture import load_record, render_run
        from tb4.sim.world import load_world

        record = load_record(record_path)
        world = world if world is not None else load_world(world_name)
        return render_run(world, record, output, title=f"tb4 run {tutorial} ({world_name})")
    except (OSError, ValueError, KeyError, MissingExtraError) as exc:
        print(f"tb4 run: could not draw the run picture: {exc}", file=sys.stderr)
        return None


def _show_state(display: Display, monitor: Any) -> None:
    """The state as each task began since the last look (a task can begin and end between two looks), the
    current state, then the monitor's events."""
    for state in monitor.pop_task_starts():
        display.update(state)
    display.update(monitor.state.snapshot())
    for event in monitor.pop_events():
        display.event(event)


def _start_tutorial_process(
    mission: Mission, options: RunOptions, env: dict[str, str], gate: StartGate
) -> subprocess.Popen[bytes]:
    """The mission as its own process, held at `gate`: an interactive one reads the user's terminal; its output
    goes through us."""
    args = [sys.executable, "-m", "tb4.runner.tutorial_start", *mission.child_args(), *options.tutorial_args]
    if options.namespace and mission.kind == "tutorial":
        args += ["--namespace", options.namespace]  # a user's script takes its own arguments
    return gate.spawn(
        args,
        env,
        stdin=None if mission.interactive else subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )


def _follow_tutorial_process(
    proc: subprocess.Popen[bytes],
    mission: Mission,
    display: Display,
    monitor: Any,
    output_lines: list[str],
    deadline: Deadline | None = None,
) -> int:
    """Show the mission's output and the robot's state until it ends; its exit status (TIMED_OUT when it was
    ended at `deadline`)."""
    interactive = mission.interactive
    assert proc.stdout is not None
    selector = selectors.DefaultSelector()
    selector.register(proc.stdout, selectors.EVENT_READ)
    pending = b""
    try:
        while True:
            for _key, _ in selector.select(timeout=0.1):
                chunk = os.read(proc.stdout.fileno(), 65536)
                if not chunk:
                    selector.unregister(proc.stdout)
                    break
                pending += chunk.replace(b"\r\n", b"\n").replace(b"\r", b"\n")  # ETA lines end in \r
                *lines, pending = pending.split(b"\n")
                for raw in lines:
                    line = raw.decode(errors="replace")
                    output_lines.append(line)
                    display.log(line)
                if pending and interactive:  # a prompt without a newline (input()): show it now
                    display.log(pending.decode(errors="replace"))
                    output_lines.append(pending.decode(errors="replace"))
                    pending = b""
            _show_state(display, monitor)
            if deadline is not None and deadline.expired and proc.poll() is None:
                display.message(f"tb4 run: {mission.name} is still running at its time limit: ending it")
                end_mission_process(proc, signal.SIGINT, MISSION_STOP_GRACE)  # its Ctrl-C handling first
                return TIMED_OUT
            if proc.poll() is not None and not selector.get_map():
                break
            if proc.poll() is not None:
                # drain what is left, then stop
                rest = proc.stdout.read() or b""
                for raw in (pending + rest).split(b"\n"):
                    if raw:
                        line = raw.decode(errors="replace")
                        output_lines.append(line)
                        display.log(line)
                pending = b""
                break
    except KeyboardInterrupt:
        end_mission_process(proc, signal.SIGINT, 15.0)  # the tutorial's own Ctrl-C handling first
        raise
    finally:
        selector.close()
    _show_state(display, monitor)
    return int(
        proc.returncode if proc.returncode is not None and proc.returncode >= 0 else 128 - (proc.returncode or 0)
    )


def end_mission_process(proc: subprocess.Popen[bytes], first: int = signal.SIGTERM, timeout: float = 10.0) -> None:
    """Stop a mission's process group if it still runs: `first`, then SIGKILL after `timeout` seconds.

    Args:
        proc: the mission's process (the leader of its own process group).
        first: the first signal (SIGINT: its own Ctrl-C handling).
        timeout: wall seconds it gets after `first`.
    """
    for sig, wait in ((first, timeout), (signal.SIGKILL, 5.0)):
        if proc.poll() is not None:
            break
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, sig)
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(timeout=wait)
    if proc.stdout is not None:
        proc.stdout.close()
