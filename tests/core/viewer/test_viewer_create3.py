"""The viewer's Create 3 panel without DDS: the page's press message, and the state snapshot carrying the ring."""

from __future__ import annotations

import pytest

from tb4.viewer.protocol import PressCommand, ProtocolError, parse_message
from tb4.viewer.state import ClientCursor, ViewerState


@pytest.mark.parametrize("button", ["button_1", "button_power", "button_2"])
def test_press_messages_name_a_faceplate_button(button: str) -> None:
    assert parse_message(f'{{"type": "press", "button": "{button}"}}') == PressCommand(button)


@pytest.mark.parametrize(
    ("text", "error"),
    [
        ('{"type": "press"}', "must be one of"),
        ('{"type": "press", "button": "button_3"}', "must be one of"),
        ('{"type": "press", "button": 1}', "must be one of"),
        ('{"type": "press", "button": "button_1", "hold": 99}', "unexpected field"),
    ],
)
def test_bad_press_messages_are_refused(text: str, error: str) -> None:
    with pytest.raises(ProtocolError, match=error):
        parse_message(text)


def test_snapshot_carries_the_light_ring_buttons_and_hazards() -> None:
    state = ViewerState()
    assert state.snapshot(ClientCursor())["create3"] is None
    state.set_create3("lightring", {"leds": [[255, 0, 0]] * 6, "override": True})
    state.set_create3("buttons", {"button_1": True, "button_power": False, "button_2": False})
    state.set_create3("hazards", ["bump (bump_front_left)"])
    c3 = state.snapshot(ClientCursor())["create3"]
    assert c3["lightring"]["leds"][0] == [255, 0, 0] and c3["buttons"]["button_1"]
    assert c3["hazards"] == ["bump (bump_front_left)"]
