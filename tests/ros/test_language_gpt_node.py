"""gpt_node in-process over DDS (no simulator): confirmation step, key handling, busy handling, ready_for_input.

The navigator here is a small recording test target (the executor only calls methods on the object it is given);
the DDS side is real: commands arrive on user_input from another node and readiness goes out on ready_for_input.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest
import rclpy
from rclpy.executors import MultiThreadedExecutor
from std_msgs.msg import Bool, String

from tb4.language.gpt_node import GptNode, GptNodeOptions
from tb4.language.scripted_server import Reply, ScriptedServer
from tb4.navigator import TaskResult

SECRET = "sk-test-NODESECRET5566778899aabb"


class Recorder:
    """Speaks the navigator's API and types (TaskResult): a goal takes `goal_seconds`, then ends `result`."""

    def __init__(self, goal_seconds: float = 0.0, result: TaskResult = TaskResult.SUCCEEDED) -> None:
        self.calls: list[str] = []
        self.goal_seconds = goal_seconds
        self.result = result
        self.threads: set[str] = set()
        self._ends = 0.0

    def _record(self, call: str) -> None:
        self.calls.append(call)
        self.threads.add(threading.current_thread().name)

    def getPoseStamped(self, position: Any, rotation: Any) -> tuple:  # noqa: N802
        return (position[0], position[1], rotation)

    def goToPose(self, pose: Any) -> bool:  # noqa: N802
        self._record(f"goToPose{pose}")
        self._ends = time.monotonic() + self.goal_seconds
        return True

    def isTaskComplete(self) -> bool:  # noqa: N802
        left = self._ends - time.monotonic()
        if left > 0:
            time.sleep(min(left, 0.05))
        return time.monotonic() >= self._ends

    def getResult(self) -> TaskResult:  # noqa: N802
        return self.result if self.isTaskComplete() else TaskResult.UNKNOWN

    def dock(self) -> bool:
        self._record("dock")
        return True

    def undock(self) -> bool:
        self._record("undock")
        return True

    def info(self, msg: str) -> None:
        self._record(f"info {msg}")

    def cancelTask(self) -> None:  # noqa: N802
        self._record("cancelTask")
        self._ends = 0.0
        self.result = TaskResult.CANCELED


class Harness:
    """gpt_node plus a commander node in one context, spun by a background thread."""

    def __init__(self, navigator: Any, options: GptNodeOptions) -> None:
        self.closed = False
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = GptNode(navigator, options, context=self.context)
        self.commander = rclpy.create_node("commander", context=self.context)
        self.ready: list[bool] = []
        self.commander.create_subscription(Bool, "ready_for_input", lambda m: self.ready.append(m.data), 10)
        self.pub = self.commander.create_publisher(String, "user_input", 10)
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.commander)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()
        deadline = time.monotonic() + 20
        while self.pub.get_subscription_count() == 0:
            assert time.monotonic() < deadline, "gpt_node did not subscribe"
            time.sleep(0.02)

    def _spin(self) -> None:
        while not self.closed and self.context.ok():
            try:
                self.executor.spin_once(timeout_sec=0.05)
            except Exception:
                if not self.context.ok():
                    return
                raise

    def say(self, text: str, outcomes: int, timeout: float = 30.0) -> None:
        self.pub.publish(String(data=text))
        assert self.node.wait_for_outcomes(outcomes, timeout), f"no outcome for {text!r}"

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        # Spinning stops before the node is destroyed, as natural_language_nav does it: destroyed while this thread
        # waits on it, rclpy raises InvalidHandle in the thread (stress run s42, Jazzy stage).
        self.thread.join(timeout=5)
        self.executor.shutdown(timeout_sec=1.0)
        self.node.shutdown()
        rclpy.try_shutdown(context=self.context)
        self.commander.destroy_node()


@pytest.fixture
def harness(monkeypatch) -> Iterator[Any]:
    monkeypatch.delenv("OPENAI_API_KEY", raising=False)  # hermetic: no key from the developer's shell
    made: list[Harness] = []

    def make(navigator: Any, **options: Any) -> Harness:
        h = Harness(navigator, GptNodeOptions(**options))
        made.append(h)
        return h

    yield make
    for h in made:
        h.close()


def test_confirmation_step_runs_only_after_yes(harness) -> None:
    nav = Recorder()
    h = harness(nav, parking_brake=False, require_confirmation=True)
    assert type(h.node.processor.backend).__name__ == "OfflineBackend"
    h.say("Move to the wooden object", 1)
    assert h.node.outcomes[-1].status == "pending" and nav.calls == []
    h.say("yes", 2)
    assert h.node.outcomes[-1].status == "executed"
    assert nav.calls == ["goToPose(0.0, 3.0, 0.0)"]
    h.say("undock", 3)
    h.say("no", 4)
    assert h.node.outcomes[-1].status == "cancelled" and nav.calls == ["goToPose(0.0, 3.0, 0.0)"]


def test_destinations_come_from_a_file_of_its_own(harness, tmp_path) -> None:
    """A real robot's places: a destinations file with no simulator world; a goal the map forbids is refused."""
    from tb4.sim.world import WORLDS_DIR

    site = tmp_path / "lab.yaml"
    site.write_text(
        f"name: lab\nmap: {WORLDS_DIR / 'depot_map.yaml'}\n"
        "destinations:\n  coffee machine: {position: [2.0, 2.0], heading: 90, aliases: [coffee]}\n"
    )
    nav = Recorder()
    h = harness(nav, parking_brake=False, destinations_file=str(site), world="")
    assert h.node.get_parameter("destinations_file").value == str(site)
    h.say("go to the coffee machine", 1)
    assert h.node.outcomes[-1].status == "executed", h.node.outcomes[-1].message
    assert nav.calls == ["goToPose(2.0, 2.0, 90.0)"]
    h.say("go to the wooden crate", 2)  # a depot world destination: not at this site
    assert h.node.outcomes[-1].status != "executed" and len(nav.calls) == 1


def test_key_parameter_is_blanked_and_never_logged(harness, capfd) -> None:
    with ScriptedServer([f"# {SECRET}\nnavigator.dock()", Reply(status=401, error=f"bad key {SECRET}")]) as server:
        nav = Recorder()
        h = harness(nav, openai_api_key=SECRET, base_url=server.base_url, parking_brake=False, max_retries=0)
        assert h.node.get_parameter("openai_api_key").value == ""
        assert SECRET not in repr(GptNodeOptions(openai_api_key=SECRET))
        h.say("Dock", 1)
        h.say("Dock", 2)
    assert [o.status for o in h.node.outcomes] == ["executed", "failed"]
    deadline = time.monotonic() + 10
    while not (h.ready and h.ready[-1] is True) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert h.ready[-1] is True, "after a model error the node must be ready for input again"
    assert nav.calls == ["dock"]
    assert "401" in h.node.outcomes[-1].message
    out, err = capfd.readouterr()
    assert "gpt_node" in out + err
    assert SECRET not in out + err
    for outcome in h.node.outcomes:
        assert SECRET not in outcome.message + outcome.program


def test_busy_commands_are_ignored_and_ready_goes_false_then_true(harness) -> None:
    nav = Recorder(goal_seconds=2.0)
    h = harness(nav, parking_brake=False)
    h.pub.publish(String(data="go to the crate"))
    deadline = time.monotonic() + 10
    while not nav.calls and time.monotonic() < deadline:
        time.sleep(0.02)
    h.say("dock", 1)  # arrives while the goal is running: ignored, the first command's outcome comes
    assert h.node.wait_for_outcomes(1, 30)
    time.sleep(1.5)
    assert len(h.node.outcomes) == 1 and "dock" not in nav.calls
    assert False in h.ready and h.ready[-1] is True
    h.say("make me a coffee", 2)
    assert h.node.outcomes[-1].status == "not_understood"


WEDGE = (
    "A0 = [1, 2, 3, 4]\n"
    + "".join(f"A{i} = [A{i - 1}, A{i - 1}, A{i - 1}, A{i - 1}]\n" for i in range(1, 21))
    + "navigator.info(A20)"
)
WEDGES = [
    WEDGE,
    WEDGE.replace("navigator.info(A20)", "navigator.startToPose(navigator.getPoseStamped(destinations[A20], 0))"),
    WEDGE.replace("navigator.info(A20)", "navigator.info(f'{A20}')"),
    "A0 = [1, 2, 3, 4]\n"
    + "".join(f"A{i} = [A{i - 1}, A{i - 1}, A{i - 1}, A{i - 1}]\n" for i in range(1, 5))
    + "x = destinations[A4]",
    "navigator.spin(spin_dist=1.0, spin_dist=2.0)",
]


def wait_ready(h: Harness, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not (h.ready and h.ready[-1] is True) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert h.ready and h.ready[-1] is True, "ready_for_input never went back to true"


@pytest.mark.parametrize("brake", [False, True], ids=["brake-off", "brake-on"])
def test_after_refusing_wedging_programs_the_node_executes_the_next_command(harness, brake) -> None:
    replies: list[str] = []
    for wedge in WEDGES:
        replies += [wedge, "navigator.dock()"]
    with ScriptedServer(replies) as server:
        nav = Recorder()
        h = harness(nav, base_url=server.base_url, parking_brake=brake, max_retries=0)
        for i, _wedge in enumerate(WEDGES):
            h.say(f"hostile {i}", 2 * i + 1, timeout=20)
            refused = h.node.outcomes[-1]
            assert refused.status == "refused", refused.message
            assert len(refused.message) < 500
            wait_ready(h)
            h.say("dock", 2 * i + 2, timeout=20)
            assert h.node.outcomes[-1].status == ("parked" if brake else "executed"), h.node.outcomes[-1].message
    assert nav.calls == ([] if brake else ["dock"] * len(WEDGES))


def test_a_failed_goal_stops_the_plan_over_dds(harness) -> None:
    with ScriptedServer(["navigator.startToPose(navigator.getPoseStamped([0.0, 3.0], 0))\nnavigator.dock()"]) as server:
        nav = Recorder(result=TaskResult.FAILED)
        h = harness(nav, base_url=server.base_url, parking_brake=False, max_retries=0)
        h.say("go then dock", 1)
    outcome = h.node.outcomes[-1]
    assert outcome.status == "failed" and "ended FAILED" in outcome.message
    assert nav.calls == ["goToPose(0.0, 3.0, 0.0)"], "dock must not run after a failed goal"


def test_shutdown_cancels_the_running_goal_from_the_worker_thread(harness) -> None:
    nav = Recorder(goal_seconds=60.0)
    h = harness(nav, parking_brake=False)
    h.pub.publish(String(data="go to the crate"))
    deadline = time.monotonic() + 10
    while not nav.calls and time.monotonic() < deadline:
        time.sleep(0.02)
    started = time.monotonic()
    h.close()
    assert time.monotonic() - started < 10.0
    assert nav.calls == ["goToPose(0.0, 3.0, 0.0)", "cancelTask"]
    assert nav.threads == {"gpt_node-worker"}, "only the worker thread may call the navigator"
