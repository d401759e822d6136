"""The model's context: our few-shot data file, destinations from the world, the command; and reply parsing."""

from __future__ import annotations

from tb4.language.executor import plan_program, validate
from tb4.language.prompt import (
    EXAMPLE_DESTINATIONS,
    PROMPT_FILE,
    build_messages,
    destinations_line,
    extract_program,
    few_shot_examples,
)


def test_few_shot_file_is_comment_then_code_and_every_example_is_a_safe_program() -> None:
    text = few_shot_examples()
    assert PROMPT_FILE.name == "few_shot_prompt.txt" and PROMPT_FILE.is_file()
    blocks: list[list[str]] = []
    for line in text.splitlines():
        if line.startswith("#"):
            blocks.append([])
        else:
            assert blocks, "the file must start with a '# comment'"
            blocks[-1].append(line)
    assert len(blocks) >= 8
    for block in blocks:
        program = "\n".join(block)
        assert program.strip()
        plan_program(program, EXAMPLE_DESTINATIONS)  # would raise ProgramRejected


def test_messages_hold_rules_examples_destinations_and_the_command(depot_context) -> None:
    table, _ = depot_context
    messages = build_messages("  Go to the   wooden object ", table)
    assert [m["role"] for m in messages] == ["system", "user"]
    system, user = messages[0]["content"], messages[1]["content"]
    assert "navigator.startToPose" in system and "No imports" in system
    assert few_shot_examples().strip() in user
    assert destinations_line(table) in user
    assert "'wood crate': [0, 3, 0]" in user
    assert user.rstrip().endswith("# Go to the wooden object")


def test_extract_program_from_fenced_and_chatty_replies() -> None:
    fenced = "Sure!\n```python\nnavigator.dock()\n```\nHope this helps."
    assert extract_program(fenced) == "navigator.dock()\n"
    echoed = "# Dock\nnavigator.dock()\n# Now go to the crate\nnavigator.undock()\n"
    assert extract_program(echoed) == "# Dock\nnavigator.dock()\n"
    assert extract_program("") == "\n"
    validate(extract_program(echoed))
