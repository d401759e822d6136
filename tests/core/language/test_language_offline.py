"""The offline interpreter: upstream's example commands, variations, honest refusals, and its evaluation set."""

from __future__ import annotations

import socket

import pytest

from tb4.language.evaluation import (
    canonical_actions,
    evaluate,
    exact_name_baseline,
    load_eval_set,
    offline_interpreter,
)
from tb4.language.executor import plan_program
from tb4.language.offline import HELP_TEXT, OfflineInterpreter


@pytest.fixture(scope="module")
def interpreter(depot) -> OfflineInterpreter:
    return OfflineInterpreter(depot.destinations.values())


def actions(interpreter: OfflineInterpreter, depot_context, text: str) -> tuple[str, ...]:
    result = interpreter.interpret(text)
    assert result.program is not None, result.message
    table, check = depot_context
    return canonical_actions(plan_program(result.program, table, check))


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("Dock", ("goto -1 0 0", "dock")),
        ("Undock", ("undock",)),
        ("Go to -1,0, face East", ("goto -1 0 270",)),
        ("Go to 5,5", ("goto 5 5 0",)),
        ("Move to the wooden object", ("goto 0 3 0",)),
        ("Navigate to the item which can hold oil", ("goto 2 2 90",)),
        ("Travel to the room containing a toilet", ("goto -6 -6 180",)),
    ],
)
def test_upstream_example_commands(interpreter, depot_context, text, expected) -> None:
    assert actions(interpreter, depot_context, text) == expected


def test_the_program_looks_like_a_model_program(interpreter) -> None:
    program = interpreter.interpret("Move to the wooden object").program
    assert program is not None
    assert program.startswith("# Move to the wooden object\n")
    assert "navigator.startToPose(navigator.getPoseStamped(destinations['wood crate']" in program


def test_sequences_and_tours(interpreter, depot_context) -> None:
    assert actions(interpreter, depot_context, "undock and go to the crate, then dock") == (
        "undock",
        "goto 0 3 0",
        "goto -1 0 0",
        "dock",
    )
    assert actions(interpreter, depot_context, "visit the barrels and the crate") == ("waypoints 2 2 90; 0 3 0",)


def test_docking_drives_to_the_approach_pose_first_unless_told_otherwise(depot) -> None:
    assert OfflineInterpreter(depot.destinations.values()).interpret("dock").program == (
        "# dock\nnavigator.startToPose(navigator.getPoseStamped(destinations['dock'][0:2], destinations['dock'][2]))"
        "\nnavigator.dock()\n"
    )
    plain = OfflineInterpreter(depot.destinations.values(), dock_approach=False)
    assert plain.interpret("dock").program == "# dock\nnavigator.dock()\n"


def test_an_exact_destination_name_wins_over_dock_words() -> None:
    from tb4.sim.world import Destination

    home = Destination("home", -1.0, 1.0, 0.0, "the mail room", ("mail room",))
    interpreter = OfflineInterpreter([home])
    assert "destinations['home']" in (interpreter.interpret("go home").program or "")
    assert "navigator.dock()" in (interpreter.interpret("go charge").program or "")


def test_heading_override_for_a_destination(interpreter, depot_context) -> None:
    assert actions(interpreter, depot_context, "go to the barrels facing west") == ("goto 2 2 90",)
    assert actions(interpreter, depot_context, "go to the barrels facing south") == ("goto 2 2 180",)


@pytest.mark.parametrize(
    "text",
    ["make me a coffee", "open the door", "don't go to the bathroom", "go to the kitchen", "", "   ", "then ; then"],
)
def test_says_clearly_when_it_does_not_understand(interpreter, text) -> None:
    result = interpreter.interpret(text)
    assert result.program is None and not result.understood
    assert HELP_TEXT in result.message


def test_user_text_cannot_inject_code_through_the_comment(interpreter, depot_context) -> None:
    result = interpreter.interpret("dock\nimport os\r\nos.system('x')")
    # newlines are folded into the comment line: whatever was understood, no import reaches the program's code
    if result.program is not None:
        code_lines = [ln for ln in result.program.splitlines() if not ln.startswith("#")]
        assert all("import" not in ln for ln in code_lines)
        table, check = depot_context
        plan_program(result.program, table, check)


def test_no_network_access(interpreter, monkeypatch) -> None:
    def refuse(*args, **kwargs):
        raise AssertionError("the offline interpreter opened a socket")

    monkeypatch.setattr(socket, "socket", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    assert interpreter.interpret("go to the loo then dock").program is not None


def test_evaluation_set_is_large_enough_and_valid() -> None:
    cases = load_eval_set()
    assert len(cases) >= 40
    assert sum(c.expect is None for c in cases) >= 5, "the set must also test refusals"
    texts = [c.text for c in cases]
    for example in ("Dock", "Go to -1,0, face East", "Travel to the room containing a toilet"):
        assert example in texts


def test_offline_accuracy_beats_exact_names_by_far(depot) -> None:
    ours = evaluate(offline_interpreter(depot), depot)
    base = evaluate(exact_name_baseline(depot), depot)
    acc_ours = sum(r.correct for r in ours) / len(ours)
    acc_base = sum(r.correct for r in base) / len(base)
    assert acc_ours >= 0.9, [r.case.text for r in ours if not r.correct]
    assert acc_base < 0.5
    assert acc_ours > acc_base + 0.4
