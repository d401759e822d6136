"""`tb4 press` and `tb4 kidnap` refuse bad arguments before touching ROS."""

from __future__ import annotations

import pytest

from tb4.cli.cmd_press import button_name
from tb4.cli.main import main


@pytest.mark.parametrize(
    ("text", "name"),
    [("1", "button_1"), ("2", "button_2"), ("power", "button_power"), (" POWER ", "button_power"),
     ("button_2", "button_2")],
)  # fmt: skip
def test_button_names(text: str, name: str) -> None:
    assert button_name(text) == name


@pytest.mark.parametrize("text", ["3", "", "one", "button_9"])
def test_unknown_buttons_are_refused(text: str) -> None:
    with pytest.raises(ValueError, match="use 1, 2 or power"):
        button_name(text)


def test_press_with_a_bad_button_exits_2(capsys) -> None:
    assert main(["press", "7"]) == 2
    assert "unknown button" in capsys.readouterr().err


@pytest.mark.parametrize("hold", ["0", "-1", "nan", "inf", "61", "long"])
def test_press_hold_must_be_a_sane_duration(hold: str, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["press", "1", "--hold", hold])
    assert exc.value.code == 2 and "hold" in capsys.readouterr().err


@pytest.mark.parametrize("args", [["1", "nan"], ["inf", "0"], ["1"], ["1", "2", "sideways"]])
def test_kidnap_needs_finite_coordinates_and_a_heading(args: list[str], capsys) -> None:
    try:
        code = main(["kidnap", *args])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
