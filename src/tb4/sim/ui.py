"""The Create 3's user interface: the light ring, the speaker and the three faceplate buttons.

cmd_lightring / cmd_audio and the led_animation / audio_note_sequence goals change this state; the simulator
publishes the buttons and shows the ring in the viewer and the run record. Times are sim seconds. Nothing here
moves the robot.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from tb4.sim.goal_state import FAILED, SUCCEEDED, GoalState

__all__ = [
    "BUTTONS",
    "Color",
    "Note",
    "ButtonState",
    "Lightring",
    "Speaker",
    "LedAnimation",
    "AudioSequence",
    "check_notes",
]

BUTTONS = ("button_1", "button_power", "button_2")
Color = tuple[int, int, int]
WHITE: Color = (255, 255, 255)
ORANGE: Color = (255, 96, 0)
OFF: Color = (0, 0, 0)
BLINK_LIGHTS, SPIN_LIGHTS = 1, 2
MAX_RUNTIME = 24 * 3600.0  # s: longer goals are rejected as garbage


@dataclass(frozen=True)
class Note:
    frequency: int  # Hz (0: a rest)
    duration: float  # s


def check_notes(notes: Sequence[Note]) -> tuple[Note, ...]:
    out = tuple(notes)
    for i, n in enumerate(out):
        if not (math.isfinite(n.duration) and 0.0 <= n.duration <= 60.0):
            raise ValueError(f"note {i}: max_runtime must be within [0, 60] s, got {n.duration!r}")
    return out


@dataclass
class ButtonState:
    is_pressed: bool = False
    last_start: float = 0.0  # sim time the last press began
    last_duration: float = 0.0  # s it was held
    release_at: float = -math.inf


class Lightring:
    """Six LEDs (index 0 at 4 o'clock, counter-clockwise as in LightringLeds). What is shown, in priority order:
    a running animation, the user's colours while `override_system`, else the system pattern (white; orange
    while the backup limit is reported, as the Create 3 does)."""

    def __init__(self) -> None:
        self.user: tuple[Color, ...] = (WHITE,) * 6
        self.override = False
        self.animation: LedAnimation | None = None
        self.system: Color = WHITE
        self.changes = 0  # counts commands, so a viewer can tell a new command from the same colours

    def command(self, leds: Sequence[Color], override: bool) -> None:
        if len(leds) != 6:
            raise ValueError(f"the light ring has 6 LEDs, got {len(leds)} colours")
        self.user = tuple((int(r), int(g), int(b)) for r, g, b in leds)
        self.override = bool(override)
        self.changes += 1

    def shown(self, now: float) -> tuple[Color, ...]:
        if self.animation is not None and not self.animation.done:
            return self.animation.frame(now)
        if self.override:
            return self.user
        return (self.system,) * 6


class _TimedGoal(GoalState):
    """A goal that runs `_total()` seconds of sim time from `start`, then succeeds with `done_reason`; a newer goal
    of its kind preempts it (failed, `preempted_reason`)."""

    done_reason = ""
    preempted_reason = ""

    def __init__(self, kind: str, start: float) -> None:
        super().__init__(kind)
        self.start = start
        self.elapsed = 0.0

    def _total(self) -> float:
        raise NotImplementedError

    def preempt(self) -> None:
        self.finish(FAILED, self.preempted_reason)

    def step(self, now: float) -> None:
        if self.done:
            return
        total = self._total()
        self.elapsed = min(now - self.start, total)
        if now - self.start >= total - 1e-9:
            self.finish(SUCCEEDED, self.done_reason)


class LedAnimation(_TimedGoal):
    """led_animation goal: blink (0.5 s on, 0.5 s off) or spin the given colours for max_runtime seconds."""

    done_reason = "animation done"
    preempted_reason = "preempted by a new led_animation"

    def __init__(self, animation_type: int, leds: Sequence[Color], max_runtime: float, start: float) -> None:
        if animation_type not in (BLINK_LIGHTS, SPIN_LIGHTS):
            raise ValueError(f"animation_type must be 1 (BLINK_LIGHTS) or 2 (SPIN_LIGHTS), got {animation_type!r}")
        if not (math.isfinite(max_runtime) and 0.0 < max_runtime <= MAX_RUNTIME):
            raise ValueError(f"max_runtime must be within (0, {MAX_RUNTIME:g}] s, got {max_runtime!r}")
        if len(leds) != 6:
            raise ValueError(f"the light ring has 6 LEDs, got {len(leds)} colours")
        super().__init__("led_animation", start)
        self.animation_type = animation_type
        self.leds = tuple(leds)
        self.max_runtime = max_runtime

    def _total(self) -> float:
        return self.max_runtime

    def frame(self, now: float) -> tuple[Color, ...]:
        t = now - self.start
        if self.animation_type == BLINK_LIGHTS:
            return self.leds if int(t / 0.5) % 2 == 0 else (OFF,) * 6
        k = int(t / 0.2) % 6
        return self.leds[k:] + self.leds[:k]

    def feedback(self) -> dict[str, Any]:
        return {"remaining_runtime": max(0.0, self.max_runtime - self.elapsed)}

    def result(self) -> dict[str, Any]:
        return {"runtime": self.elapsed}


class AudioSequence(_TimedGoal):
    """audio_note_sequence goal: play the notes `iterations` times (-1: until canceled)."""

    INFINITE = -1
    done_reason = "sequence played"
    preempted_reason = "preempted by other audio"

    def __init__(self, notes: Sequence[Note], iterations: int, start: float) -> None:
        self.notes = check_notes(notes)
        if not self.notes:
            raise ValueError("note_sequence has no notes")
        if iterations == 0 or iterations < self.INFINITE:
            raise ValueError(f"iterations must be positive or -1 (INFINITE), got {iterations}")
        self.period = sum(n.duration for n in self.notes)
        if self.period <= 0.0:
            raise ValueError("the notes last 0 s in total: nothing to play")
        super().__init__("audio_note_sequence", start)
        self.iterations = iterations

    def _total(self) -> float:
        return self.period * self.iterations if self.iterations > 0 else math.inf

    @property
    def played(self) -> int:
        return int(self.elapsed / self.period + 1e-9)

    def note_at(self, now: float) -> int:
        t = (now - self.start) % self.period
        for n in self.notes:
            if t < n.duration:
                return n.frequency
            t -= n.duration
        return 0

    def feedback(self) -> dict[str, Any]:
        return {"iterations_played": self.played, "current_runtime": self.elapsed}

    def result(self) -> dict[str, Any]:
        complete = self.status == SUCCEEDED
        return {"complete": complete, "iterations_played": self.played, "runtime": self.elapsed}


class Speaker:
    """cmd_audio queue (append or replace) and the audio goal; keeps a short log of what was played."""

    def __init__(self) -> None:
        self.queue: deque[tuple[float, Note]] = deque()  # (start time, note)
        self.sequence: AudioSequence | None = None
        self.log: deque[tuple[float, int, float]] = deque(maxlen=200)  # (start, frequency, duration)

    def command(self, notes: Sequence[Note], append: bool, now: float) -> None:
        notes = check_notes(notes)
        if not append:
            self.queue.clear()
        t = max(now, self.queue[-1][0] + self.queue[-1][1].duration) if self.queue else now
        for n in notes:
            self.queue.append((t, n))
            self.log.append((t, n.frequency, n.duration))
            t += n.duration

    def playing(self, now: float) -> int:
        """Frequency sounding now (0: silent)."""
        if self.sequence is not None and not self.sequence.done:
            return self.sequence.note_at(now)
        while self.queue and self.queue[0][0] + self.queue[0][1].duration <= now:
            self.queue.popleft()
        if self.queue and self.queue[0][0] <= now:
            return self.queue[0][1].frequency
        return 0
