"""Command handling without ROS: backend -> checked plan -> navigator, with the parking brake and refusals."""

from __future__ import annotations

import pytest
from language_test_targets import RecordingNavigator
from test_language_executor import HOSTILE

from tb4.language.commands import CommandProcessor, ModelBackend, OfflineBackend, Outcome, Prepared
from tb4.language.model_client import ModelClient, ModelSettings
from tb4.language.offline import OfflineInterpreter
from tb4.language.scripted_server import ScriptedServer

SECRET = "sk-test-ANOTHERSECRET9876543210"


class ListLogger:
    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def info(self, msg: str) -> None:
        self.lines.append(("info", msg))

    def warn(self, msg: str) -> None:
        self.lines.append(("warn", msg))

    def error(self, msg: str) -> None:
        self.lines.append(("error", msg))

    def text(self) -> str:
        return "\n".join(m for _, m in self.lines)


def processor(
    depot, depot_context, backend, parking_brake: bool
) -> tuple[CommandProcessor, RecordingNavigator, ListLogger]:
    table, check = depot_context
    navigator, log = RecordingNavigator(), ListLogger()
    return CommandProcessor(backend, navigator, table, check, log, parking_brake=parking_brake), navigator, log


def test_offline_command_moves_the_robot_when_the_brake_is_off(depot, depot_context) -> None:
    proc, nav, log = processor(
        depot, depot_context, OfflineBackend(OfflineInterpreter(depot.destinations.values())), False
    )
    outcome = proc.handle("Move to the wooden object")
    assert outcome.status == "executed"
    assert nav.calls == [("goToPose", ((0.0, 3.0, 0.0),))]
    assert "Program (offline)" in log.text()


def test_parking_brake_logs_the_program_and_does_not_move(depot, depot_context) -> None:
    proc, nav, log = processor(
        depot, depot_context, OfflineBackend(OfflineInterpreter(depot.destinations.values())), True
    )
    outcome = proc.handle("Go to -1,0, face East")
    assert outcome.status == "parked" and nav.calls == []
    assert "navigator.startToPose(navigator.getPoseStamped([-1.0, 0.0], TurtleBot4Directions.EAST))" in log.text()
    assert "Parking brake is on" in log.text()


def test_not_understood_is_reported_and_nothing_moves(depot, depot_context) -> None:
    proc, nav, log = processor(
        depot, depot_context, OfflineBackend(OfflineInterpreter(depot.destinations.values())), False
    )
    outcome = proc.handle("bake a cake")
    assert outcome.status == "not_understood" and nav.calls == []
    assert ("warn", outcome.message) in log.lines


class ScriptedBackend:
    name = "scripted"

    def __init__(self, programs: list[str]) -> None:
        self.programs = list(programs)

    def program_for(self, text: str):
        from tb4.language.commands import BackendAnswer

        return BackendAnswer(self.programs.pop(0))


def test_every_hostile_program_is_refused_and_the_processor_still_answers(depot, depot_context) -> None:
    programs = [p for _, p in HOSTILE] + ["navigator.dock()"]
    proc, nav, log = processor(depot, depot_context, ScriptedBackend(programs), False)
    for ident, _ in HOSTILE:
        outcome = proc.handle(ident)
        assert outcome.status == "refused", ident
        assert nav.calls == [], ident
    assert proc.handle("dock").status == "executed"
    assert nav.calls == [("dock", ())]
    assert sum(1 for level, m in log.lines if level == "error" and "refused" in m) == len(HOSTILE)


def test_model_backend_end_to_end_through_the_sdk(depot, depot_context) -> None:
    table, _ = depot_context
    with ScriptedServer([f"```python\n# {SECRET}\nnavigator.undock()\nnavigator.dock()\n```"]) as server:
        # a chat model (asked with stop "\n#", which this scripted server ignores): the echoed key reaches us
        settings = ModelSettings(model="scripted-chat-model", base_url=server.base_url, api_key=SECRET, max_retries=0)
        client = ModelClient(settings)
        proc, nav, log = processor(depot, depot_context, ModelBackend(client, table), False)
        proc.redact = client.redact
        outcome = proc.handle("undock then dock")
    assert outcome.status == "executed"
    assert [c[0] for c in nav.calls] == ["undock", "dock"]
    assert SECRET not in log.text(), "a key echoed by the model must not reach the log"


def test_prepare_then_run_is_the_confirmation_path(depot, depot_context) -> None:
    proc, nav, _ = processor(
        depot, depot_context, OfflineBackend(OfflineInterpreter(depot.destinations.values())), False
    )
    prepared = proc.prepare("dock")
    assert isinstance(prepared, Prepared) and nav.calls == []
    outcome = proc.run(prepared)
    assert isinstance(outcome, Outcome) and outcome.status == "executed"
    assert nav.calls == [("goToPose", ((-1.0, 0.0, 0.0),)), ("dock", ())]


@pytest.mark.parametrize("brake", [True, False])
def test_navigator_exceptions_do_not_escape(depot, depot_context, brake) -> None:
    class Broken(RecordingNavigator):
        def dock(self) -> None:
            raise RuntimeError("action server gone")

    table, check = depot_context
    log = ListLogger()
    proc = CommandProcessor(
        OfflineBackend(OfflineInterpreter(depot.destinations.values())),
        Broken(),
        table,
        check,
        log,
        parking_brake=brake,
    )
    outcome = proc.handle("dock")
    assert outcome.status == ("parked" if brake else "failed")


def test_terminal_escapes_from_a_model_are_not_logged_raw(depot, depot_context) -> None:
    proc, nav, log = processor(depot, depot_context, ScriptedBackend(["navigator.info('\x1b[2J hi')\n"]), False)
    assert proc.handle("x").status == "executed"
    assert "\x1b" not in log.text() and "\\x1b[2J" in log.text()
    assert nav.calls == [("info", (" [2J hi",))], "log messages of programs carry no control characters"


def test_every_bomb_is_refused_with_a_short_log_line_and_the_next_command_runs(depot, depot_context) -> None:
    from test_language_budgets import BOMBS

    programs: list[str] = []
    for _, bomb in BOMBS:
        programs += [bomb, "navigator.dock()"]
    proc, nav, log = processor(depot, depot_context, ScriptedBackend(programs), False)
    for ident, _ in BOMBS:
        nav.calls.clear()
        outcome = proc.handle(ident)
        assert outcome.status == "refused", ident
        assert len(outcome.message) < 500, ident
        assert nav.calls == [], ident
        assert proc.handle("dock").status == "executed", f"not answering after {ident}"
        assert nav.calls == [("dock", ())]
    assert max(len(m) for level, m in log.lines if level == "error") < 500


def test_a_planner_failure_is_reported_as_a_failure_not_a_refusal(depot, depot_context) -> None:
    table, _ = depot_context

    def out_of_memory(x: float, y: float) -> None:
        raise MemoryError

    log = ListLogger()
    program = "navigator.startToPose(navigator.getPoseStamped([1.0, 1.0], 0))"
    proc = CommandProcessor(ScriptedBackend([program]), RecordingNavigator(), table, out_of_memory, log, False)
    outcome = proc.handle("go")
    assert outcome.status == "failed"
    assert outcome.message.startswith("Planning failed (out of memory), nothing was executed")
    assert proc.navigator.calls == []


def test_a_giant_reply_from_a_model_is_logged_cut(depot, depot_context) -> None:
    proc, nav, log = processor(depot, depot_context, ScriptedBackend(["navigator.dock()\n" * 100_000]), False)
    outcome = proc.handle("dock a lot")
    assert outcome.status == "refused" and "program too long" in outcome.message
    assert len(log.text()) < 10_000 and nav.calls == []


def test_a_failed_step_is_reported_with_its_reason(depot, depot_context) -> None:
    from tb4.navigator import TaskResult

    table, check = depot_context
    log = ListLogger()
    nav = RecordingNavigator(results={"goToPose": TaskResult.FAILED})
    backend = OfflineBackend(OfflineInterpreter(depot.destinations.values()))
    outcome = CommandProcessor(backend, nav, table, check, log, parking_brake=False).handle("dock")
    assert outcome.status == "failed"
    assert outcome.message == "Stopped after 0/2 steps: startToPose((-1, 0, 0°)) ended FAILED"
    assert [c[0] for c in nav.calls] == ["goToPose"], "the dock must not run after a failed goal"
