"""A user's navigator script ends on SIGTERM as on Ctrl-C (SIGINT): its running goal is canceled and the process
exits, non-zero, within 2 s; SIGTERM with status 143 (SystemExit), SIGINT by KeyboardInterrupt. Also when the
simulator has died first. The scripts are written as upstream's examples are, with upstream's import paths, and
run as programs of their own against a real simulator."""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import pytest
from action_msgs.msg import GoalStatus

from .test_navigator_liveness import Statuses, kill

EXIT_WITHIN = 2.0  # wall s from the signal to the script's exit

# startToPose blocks until the goal ends (TurtleBot 4 tutorials); the Simple Commander loop polls (Nav2's examples)
SCRIPTS = {
    "turtlebot4": """
        import sys

        import rclpy
        from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

        rclpy.init()
        navigator = TurtleBot4Navigator(namespace=sys.argv[1])
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST))
        print("the goal ended", flush=True)
        rclpy.shutdown()
    """,
    # a user's clean-up on the way out: the navigator destroyed and rclpy shut down, in `finally`
    "turtlebot4_cleanup": """
        import sys

        import rclpy
        from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

        rclpy.init()
        navigator = TurtleBot4Navigator(namespace=sys.argv[1])
        try:
            navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
            navigator.waitUntilNav2Active()
            navigator.undock()
            navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST))
            print("the goal ended", flush=True)
        finally:
            navigator.destroy_node()
            rclpy.try_shutdown()
    """,
    "simple_commander": """
        import sys

        import rclpy
        from geometry_msgs.msg import PoseStamped
        from nav2_simple_commander.robot_navigator import BasicNavigator, TaskResult

        rclpy.init()
        navigator = BasicNavigator(namespace=sys.argv[1])
        initial_pose = PoseStamped()
        initial_pose.header.frame_id = "map"
        initial_pose.pose.orientation.w = 1.0
        navigator.setInitialPose(initial_pose)
        navigator.waitUntilNav2Active()
        goal_pose = PoseStamped()
        goal_pose.header.frame_id = "map"
        goal_pose.pose.position.x = 3.0
        goal_pose.pose.position.y = 9.0
        goal_pose.pose.orientation.w = 1.0
        navigator.goToPose(goal_pose)
        i = 0
        while not navigator.isTaskComplete():
            i += 1
            feedback = navigator.getFeedback()
            if feedback and i % 5 == 0:
                print(f"Distance remaining: {feedback.distance_remaining:.2f} m", flush=True)
        print("the goal ended:", navigator.getResult(), flush=True)
        rclpy.shutdown()
    """,
    # the navigator built and run in a thread of the script's own: no navigator handler (Python sets handlers in
    # the main thread only), so rclpy's SIGTERM handler shuts the context down and the navigator's wait sees it
    "threaded": """
        import sys
        import threading

        import rclpy
        from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

        def mission():
            navigator = TurtleBot4Navigator(namespace=sys.argv[1])
            navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
            navigator.waitUntilNav2Active()
            navigator.undock()
            try:
                navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST))
                print("the goal ended", flush=True)
            except Exception as exc:
                print(f"the mission ended: {exc}", flush=True)

        rclpy.init()
        worker = threading.Thread(target=mission)
        worker.start()
        worker.join()
        sys.exit(1)
    """,
    # the user's own SIGTERM handler, set before rclpy.init: rclpy shuts the context down in a thread of its own and
    # calls it, so the handler may run before, while or after the context goes down
    "own_handler": """
        import signal
        import sys
        import time

        import rclpy
        from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

        def on_sigterm(signum, frame):
            if sys.argv[2:] == ["--after-shutdown"]:  # the test's way to fix the race: cancel once it is down
                deadline = time.monotonic() + 1.0
                while rclpy.ok() and time.monotonic() < deadline:
                    time.sleep(0.005)
                print(f"context shut down before the cancel: {not rclpy.ok()}", flush=True)
            navigator.cancelTask()
            sys.exit(3)

        signal.signal(signal.SIGTERM, on_sigterm)
        rclpy.init()
        navigator = TurtleBot4Navigator(namespace=sys.argv[1])
        navigator.setInitialPose(navigator.getPoseStamped([0.0, 0.0], TurtleBot4Directions.NORTH))
        navigator.waitUntilNav2Active()
        navigator.undock()
        navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], TurtleBot4Directions.EAST))
        print("the goal ended", flush=True)
    """,
}


# Prepended to a script: the test's stand-in for a busy executor. The navigator takes navigate_to_pose's goal
# response but never handles it, so the goal runs on the server while the navigator has no handle for it.
HOLD_GOAL_RESPONSE = """
    from tb4.ros.action_client import ActionClient

    _execute = ActionClient.execute

    async def _execute_holding(self, taken_data):
        if taken_data and "goal" in taken_data and self._action_name.endswith("navigate_to_pose"):
            taken_data = {key: value for key, value in taken_data.items() if key != "goal"}
            print("the goal response is held", flush=True)
        await _execute(self, taken_data)

    ActionClient.execute = _execute_holding
"""


# Prepended to a script: the main thread stops inside the navigate_to_pose goal's send, right after the request went
# out and with the client's lock held, as a thread the scheduler preempts there does: the spin thread then waits for
# that lock to take any answer of this client (the goal's response, a cancel's).
STOPPED_IN_SEND = """
    import time

    from tb4.ros.action_client import ActionClient

    _add_future = ActionClient.add_future
    _stopped = []

    def _add_future_after_a_stop(self, future):
        if self._action_name.endswith("navigate_to_pose") and not _stopped:
            _stopped.append(True)
            print("stopped inside the goal's send", flush=True)
            time.sleep(60.0)
        _add_future(self, future)

    ActionClient.add_future = _add_future_after_a_stop
"""


# Prepended to a script: its navigator's spin thread stops in a turn once the goal is being sent and stays there, as
# one blocked on a context that rclpy is shutting down does.
STUCK_SPIN_THREAD = """
    import threading
    import time

    from tb4.ros.background import BackgroundSpinner
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Navigator

    _stuck = threading.Event()
    _turn = BackgroundSpinner.turn

    def _turn_or_stay(self):
        if _stuck.is_set() and threading.current_thread().name.startswith("navigator-spin"):
            print("the spin thread is stuck", flush=True)
            time.sleep(60.0)
        _turn(self)

    BackgroundSpinner.turn = _turn_or_stay
    _start_to_pose = TurtleBot4Navigator.startToPose

    def _start_to_pose_stuck(self, pose):
        _stuck.set()
        return _start_to_pose(self, pose)

    TurtleBot4Navigator.startToPose = _start_to_pose_stuck
"""


def start_script(
    start_process, tmp_path: Path, kind: str, namespace: str, prelude: str = "", args: tuple[str, ...] = ()
) -> Any:
    script = tmp_path / f"{kind}_script.py"
    script.write_text(textwrap.dedent(prelude) + textwrap.dedent(SCRIPTS[kind]))
    return start_process([sys.executable, str(script), namespace, *args], name=f"{kind}_script")


def signal_and_time_exit(proc: Any, sig: int) -> tuple[int, float]:
    """Send `sig` to the script; returns its exit status and the wall seconds it took to exit (fails after 20 s)."""
    sent = kill(proc, sig)
    try:
        code = proc.popen.wait(20)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"the script still ran 20 s after {signal.Signals(sig).name}:\n{proc.output()}") from None
    took = time.monotonic() - sent
    print(f"the script exited with status {code} {took:.2f} s after {signal.Signals(sig).name}")
    return code, took


def assert_cancel_answered(output: str) -> None:
    """A cancel the signal's handler sent was answered before the script ended: an answer proves the server has the
    request, which a process that ends at once can otherwise take with it (the goal then runs on)."""
    for sent in re.finditer(r"\] SIG\w+: cancel of the running '(\w+)' goal sent", output):
        answered = rf"\] SIG\w+: the '{sent.group(1)}' server (accepted|answered) the cancel"
        assert re.search(answered, output), f"no answer to the cancel of {sent.group(1)!r} before the exit:\n{output}"


def expected_status(sig: int) -> tuple[int, ...]:
    # SIGTERM: SystemExit(143); SIGINT: an uncaught KeyboardInterrupt, by which Python ends as killed by SIGINT
    return (143,) if sig == signal.SIGTERM else (-signal.SIGINT, 130)


@pytest.mark.parametrize(
    ("kind", "sig"),
    [("turtlebot4", signal.SIGTERM), ("simple_commander", signal.SIGTERM), ("simple_commander", signal.SIGINT)],
    ids=["startToPose-SIGTERM", "isTaskComplete-SIGTERM", "isTaskComplete-SIGINT"],
)
def test_a_signal_cancels_the_goal_and_ends_the_script(start_simulator, start_process, ros, tmp_path, kind, sig):
    namespace = f"signal_{kind}_{signal.Signals(sig).name.lower()}"
    statuses = Statuses(ros, f"/{namespace}/navigate_to_pose")
    start_simulator("--rate", "3", "--world", "warehouse", "--namespace", namespace)
    script = start_script(start_process, tmp_path, kind, namespace)
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the script's goal executing", timeout=90, while_running=script)

    code, took = signal_and_time_exit(script, sig)
    output = script.output()
    assert code in expected_status(sig), output
    assert took < EXIT_WITHIN, f"exited {took:.2f} s after the signal:\n{output}"
    assert "the goal ended" not in output
    assert_cancel_answered(output)
    # Who sends the cancel depends on timing: the signal's handler says so on stderr, unless a navigator wait that
    # found the context shut down sent it first and the goal had ended CANCELED by the time the handler looked.
    # Either way the simulator canceled it and the robot stopped.
    statuses.wait_for(ros, GoalStatus.STATUS_CANCELED, "the goal canceled")
    assert not statuses.seen(GoalStatus.STATUS_SUCCEEDED)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
@pytest.mark.parametrize(
    ("where", "kind", "prelude", "said"),
    [
        # the navigator took the goal response but has not handled it (it has no goal handle)
        ("held", "turtlebot4", HOLD_GOAL_RESPONSE, "the goal response is held"),
        # the main thread is inside the goal's send, holding the action client's lock, which the spin thread then
        # waits for: the cancel goes out without the lock, and its answer is taken without it too
        ("in_send", "simple_commander", STOPPED_IN_SEND, "stopped inside the goal's send"),
    ],
    ids=["response-held", "stopped-in-send"],
)
def test_a_signal_cancels_a_goal_whose_acceptance_the_navigator_has_not_handled(
    start_simulator, start_process, ros, tmp_path, sig, where, kind, prelude, said
) -> None:
    """The signal comes after the server accepted the goal, before the navigator handled the goal response: the
    cancel goes out by the goal's id all the same, its answer comes before the exit, and the robot stops."""
    namespace = f"signal_{where}_{signal.Signals(sig).name.lower()}"
    statuses = Statuses(ros, f"/{namespace}/navigate_to_pose")
    start_simulator("--rate", "3", "--world", "warehouse", "--namespace", namespace)
    script = start_script(start_process, tmp_path, kind, namespace, prelude=prelude)
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the script's goal executing", timeout=90, while_running=script)
    assert script.wait_for_output(said, timeout=10), script.output()

    code, took = signal_and_time_exit(script, sig)
    output = script.output()
    assert code in expected_status(sig), output
    assert took < EXIT_WITHIN, f"exited {took:.2f} s after the signal:\n{output}"
    assert "cancel of the running 'navigate_to_pose' goal sent" in output, output
    assert_cancel_answered(output)
    # the cancel is sent by the signal's handler or by the navigator's wait that found the context shut down first
    statuses.wait_for(ros, GoalStatus.STATUS_CANCELED, "the goal canceled")
    assert not statuses.seen(GoalStatus.STATUS_SUCCEEDED)


@pytest.mark.parametrize(
    ("kind", "args", "status", "said"),
    [
        # the navigator's wait finds the context shut down, cancels, and raises (printed by the script)
        ("threaded", (), 1, r"the mission ended: .*the cancel of 'navigate_to_pose' was sent and accepted"),
        # the handler's cancelTask once rclpy has shut the context down: the cancel goes out and is answered by hand
        (
            "own_handler",
            ("--after-shutdown",),
            3,
            r"context shut down before the cancel: True\n.*the cancel of 'navigate_to_pose' was sent and accepted",
        ),
        # as a user writes it, racing rclpy's shutdown: mostly the context goes down while the cancel waits for its
        # answer (taken by hand and said); should the answer come first, the cancel ends as any other, unsaid
        ("own_handler", (), 3, None),
    ],
    ids=["navigator-in-a-thread", "users-own-handler-after-shutdown", "users-own-handler"],
)
def test_without_our_handler_sigterm_cancels_and_hears_the_answer(
    start_simulator, start_process, ros, tmp_path, kind, args, status, said
) -> None:
    """No handler of the navigator's runs (it was built in another thread, or the script has a SIGTERM handler of
    its own): the cancel sent once the context is shut down waits for its answer, taken by hand (the spin thread has
    ended), so the script's exit cannot take the request along, and the answer is said. A user's handler that
    cancels ends with its own status, not with an exception out of the navigator."""
    namespace = f"signal_{kind}"
    statuses = Statuses(ros, f"/{namespace}/navigate_to_pose")
    start_simulator("--rate", "3", "--world", "warehouse", "--namespace", namespace)
    script = start_script(start_process, tmp_path, kind, namespace, args=args)
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the script's goal executing", timeout=90, while_running=script)

    code, took = signal_and_time_exit(script, signal.SIGTERM)
    output = script.output()
    assert code == status, output
    assert took < EXIT_WITHIN, f"exited {took:.2f} s after SIGTERM:\n{output}"
    assert "SIGTERM: cancel" not in output, output  # no handler of ours sent it
    if said is not None:
        assert re.search(said, output, re.DOTALL), output
    statuses.wait_for(ros, GoalStatus.STATUS_CANCELED, "the goal canceled")
    assert not statuses.seen(GoalStatus.STATUS_SUCCEEDED)


def test_sigterm_ends_the_script_when_the_simulator_died(start_simulator, start_process, ros, tmp_path) -> None:
    namespace = "signal_dead_simulator"
    statuses = Statuses(ros, f"/{namespace}/navigate_to_pose")
    sim = start_simulator("--rate", "3", "--world", "warehouse", "--namespace", namespace)
    script = start_script(start_process, tmp_path, "turtlebot4", namespace)
    statuses.wait_for(ros, GoalStatus.STATUS_EXECUTING, "the script's goal executing", timeout=90, while_running=script)
    kill(sim)
    time.sleep(0.5)  # well before the navigator would take the server for gone (server_lost: 5 s)

    code, took = signal_and_time_exit(script, signal.SIGTERM)
    output = script.output()
    assert code == 143, output
    assert took < EXIT_WITHIN, f"exited {took:.2f} s after SIGTERM:\n{output}"
    assert "SIGTERM: cancel of the running 'navigate_to_pose' goal sent" in output, output


def test_sigterm_ends_the_script_whose_spin_thread_cannot_end(start_simulator, start_process, tmp_path) -> None:
    """The process ends by os._exit after SIGTERM, with no interpreter finalization for a spin thread in rclpy's C++
    to abort, so no stop waits for one: a script's clean-up (destroy_node) and the exit handlers each waited their
    whole timeout for a spin thread that could not end."""
    namespace = "signal_stuck_spinner"
    start_simulator("--rate", "3", "--world", "warehouse", "--namespace", namespace)
    script = start_script(start_process, tmp_path, "turtlebot4_cleanup", namespace, prelude=STUCK_SPIN_THREAD)
    assert script.wait_for_output("the spin thread is stuck", timeout=90), script.output()

    code, took = signal_and_time_exit(script, signal.SIGTERM)
    output = script.output()
    assert code == 143, output
    assert took < EXIT_WITHIN, f"exited {took:.2f} s after SIGTERM:\n{output}"
    assert "the goal ended" not in output
