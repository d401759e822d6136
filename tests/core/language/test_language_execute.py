"""Executing a plan: every task step's result is checked against the real TaskResult, a failure stops the plan
with the reason, waits are bounded and event-driven, and the navigator is only ever called from one thread."""

from __future__ import annotations

import threading
import time

import pytest
from language_test_targets import RecordingNavigator

from tb4.language.executor import Limits, execute_plan, plan_program
from tb4.navigator import TaskResult

WOOD = "navigator.getPoseStamped(destinations['wood crate'][0:2], destinations['wood crate'][2])"
TASKS = {
    "goToPose": f"navigator.startToPose({WOOD})",
    "goThroughPoses": f"navigator.startThroughPoses([{WOOD}])",
    "followWaypoints": f"navigator.startFollowWaypoints([{WOOD}])",
    "spin": "navigator.spin(1.0)",
    "backup": "navigator.backup(0.2, 0.1)",
    "driveOnHeading": "navigator.driveOnHeading(0.3, 0.1)",
}


def test_task_result_is_the_navigators_plain_enum() -> None:
    # The old executor called int() on it: a TypeError it then read as "no failure".
    with pytest.raises(TypeError):
        int(TaskResult.FAILED)  # type: ignore[call-overload]


@pytest.mark.parametrize("result", [TaskResult.FAILED, TaskResult.CANCELED, TaskResult.UNKNOWN], ids=lambda r: r.name)
@pytest.mark.parametrize("method", list(TASKS))
def test_a_task_that_does_not_succeed_stops_the_plan(method, result, depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(results={method: result})
    program = f"navigator.info('before')\n{TASKS[method]}\nnavigator.dock()\nnavigator.info('after')"
    plan = plan_program(program, table, check)
    report = execute_plan(plan, navigator)
    assert not report.ok
    assert report.completed == 1 and report.total == 4
    assert f"ended {result.name}" in report.stopped
    names = [c[0] for c in navigator.calls]
    assert names == ["info", method], "nothing may run after a failed step"


@pytest.mark.parametrize("method", list(TASKS))
def test_a_task_the_server_rejects_stops_the_plan(method, depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(accept=False)
    report = execute_plan(plan_program(f"{TASKS[method]}\nnavigator.dock()", table, check), navigator)
    assert "was rejected" in report.stopped and report.completed == 0
    assert [c[0] for c in navigator.calls] == [method]


@pytest.mark.parametrize("method", ["dock", "undock"])
def test_a_dock_or_undock_that_does_not_succeed_stops_the_plan(method, depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(dock_ok=False)
    report = execute_plan(plan_program(f"navigator.{method}()\nnavigator.spin()", table, check), navigator)
    assert report.stopped == f"{method} did not succeed" and report.completed == 0
    assert [c[0] for c in navigator.calls] == [method]


def test_every_successful_step_runs_in_order(depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator()
    program = "navigator.undock()\n" + "\n".join(TASKS.values()) + "\nnavigator.dock()"
    report = execute_plan(plan_program(program, table, check), navigator)
    assert report.ok and report.completed == 8
    assert [c[0] for c in navigator.calls] == ["undock", *TASKS, "dock"]


def test_run_time_budget_cancels_the_running_goal_and_stops(depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(block_on_goal=True)
    plan = plan_program(f"navigator.startToPose({WOOD})\nnavigator.dock()\n", table, check)
    started = time.monotonic()
    report = execute_plan(plan, navigator, Limits(max_run_seconds=0.3))
    assert time.monotonic() - started < 20.0
    assert "run-time limit of 0.3 s" in report.stopped
    assert [c[0] for c in navigator.calls] == ["goToPose", "cancelTask"]


def test_a_behaviour_that_outlives_its_time_allowance_is_cancelled_and_stops_the_plan(depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(block_on_goal=True)
    plan = plan_program("navigator.spin(3.14, 1)\nnavigator.dock()\n", table, check)
    report = execute_plan(plan, navigator, Limits(task_grace_seconds=0.2))
    assert [c[0] for c in navigator.calls] == ["spin", "cancelTask"]
    assert "did not finish within 1.2 s" in report.stopped and report.completed == 0


def test_waiting_is_not_a_busy_loop(depot_context) -> None:
    """A navigator whose isTaskComplete() answers at once still gets at most ~1/poll_seconds checks a second."""
    table, check = depot_context

    class Instant(RecordingNavigator):
        def isTaskComplete(self) -> bool:  # noqa: N802
            self.polls += 1
            return self._done.is_set()

    navigator = Instant(block_on_goal=True)
    plan = plan_program("navigator.spin(3.14, 1)", table, check)
    execute_plan(plan, navigator, Limits(task_grace_seconds=0.0, poll_seconds=0.05))
    # 1 s of waiting at one check per 50 ms: about 20 checks (a spin loop would make hundreds of thousands).
    assert navigator.polls < 200


def test_stop_from_another_thread_is_acted_on_by_the_executing_thread(depot_context) -> None:
    table, check = depot_context
    navigator = RecordingNavigator(block_on_goal=True)
    plan = plan_program(f"navigator.startToPose({WOOD})\nnavigator.dock()", table, check)
    stop = threading.Event()
    result: list = []
    worker = threading.Thread(target=lambda: result.append(execute_plan(plan, navigator, stop=stop)), name="exec")
    worker.start()
    deadline = time.monotonic() + 10
    while not navigator.calls and time.monotonic() < deadline:
        time.sleep(0.01)
    stop.set()
    worker.join(10)
    assert not worker.is_alive()
    assert result[0].stopped.endswith("cancelled: stopped on request")
    assert [c[0] for c in navigator.calls] == ["goToPose", "cancelTask"]
    assert navigator.threads == {"exec"}, "only the executing thread may call the navigator (cancel included)"


def test_a_stop_before_the_first_step_runs_nothing(depot_context) -> None:
    table, check = depot_context
    stop = threading.Event()
    stop.set()
    navigator = RecordingNavigator()
    report = execute_plan(plan_program("navigator.undock()", table, check), navigator, stop=stop)
    assert report.stopped == "stopped on request" and navigator.calls == []


def test_the_failure_reason_includes_the_navigators_error(depot_context) -> None:
    table, check = depot_context

    class WithError(RecordingNavigator):
        def getTaskError(self) -> tuple[int, str]:  # noqa: N802
            return 104, "no valid path " * 100

    navigator = WithError(results={"goToPose": TaskResult.FAILED})
    report = execute_plan(plan_program(f"navigator.startToPose({WOOD})", table, check), navigator)
    assert "ended FAILED (error 104: no valid path" in report.stopped
    assert len(report.stopped) < 300


def test_a_navigator_call_that_raises_stops_the_plan_and_says_which(depot_context) -> None:
    table, check = depot_context

    class Broken(RecordingNavigator):
        def isTaskComplete(self) -> bool:  # noqa: N802
            raise RuntimeError("action server gone " * 100)

    navigator = Broken()
    plan = plan_program(f"navigator.info('x')\nnavigator.startToPose({WOOD})\nnavigator.dock()", table, check)
    report = execute_plan(plan, navigator)
    assert report.completed == 1
    assert report.stopped.startswith("startToPose((0, 3, 0°)) raised RuntimeError: action server gone")
    assert len(report.stopped) <= 300
    assert [c[0] for c in navigator.calls] == ["info", "goToPose", "cancelTask"], "the started goal is cancelled"
