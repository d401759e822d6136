"""Offline interpreter: plain-English robot commands -> a program for the safe executor, with no network at all.

It covers the upstream tutorial's example commands and their everyday variations: dock / undock, "go to X,Y
[facing DIRECTION]", named destinations by name, alias or description words ("the wooden object", "the item which
can hold oil"), a few behaviours (spin, turn around, back up, stop) and sequences ("... then ..."). It writes the
same kind of program a language model would, so its output goes through the same validator and executor. When it
does not understand, it says so and lists what it can do, instead of guessing.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

from tb4.core.directions import DIRECTIONS
from tb4.language.world_context import DOCK_DESTINATION
from tb4.sim.world import Destination

__all__ = ["Interpretation", "OfflineInterpreter", "HELP_TEXT"]

HELP_TEXT = (
    "I understand: 'dock', 'undock', 'go to X, Y [facing north|east|south|west|...]', "
    "'go to <destination>' (by name or description), 'spin', 'turn around', 'back up', 'stop', "
    "and sequences joined with 'then'."
)

_NUMBER = r"[-+−]?\d+(?:\.\d+)?"
_SEQUENCE_SPLIT = re.compile(
    r"\s*(?:;|,?\s*\b(?:and then|then|after that|afterwards|and finally|finally|next(?!\s+to\b))\b)\s*"
)
_NEGATION = re.compile(r"\b(?:don'?t|do not|never|not|no)\b")
_NAV_VERBS = re.compile(
    r"\b(?:go|goes|going|move|navigate|travel|drive|head|walk|roll|proceed|take me|bring me|get to|visit|"
    r"find|reach|return|come|approach|run)\b|^to\b"
)
_DIRECTION_WORDS = [
    (r"north[\s-]?west|northwest|\bnw\b", "NORTH_WEST"),
    (r"north[\s-]?east|northeast|\bne\b", "NORTH_EAST"),
    (r"south[\s-]?west|southwest|\bsw\b", "SOUTH_WEST"),
    (r"south[\s-]?east|southeast|\bse\b", "SOUTH_EAST"),
    (r"\bnorth\b|\bup\b", "NORTH"),
    (r"\bsouth\b|\bdown\b", "SOUTH"),
    (r"\beast\b", "EAST"),
    (r"\bwest\b", "WEST"),
]
_FACING = re.compile(r"\b(?:fac(?:e|ing)|head(?:ing)?|point(?:ing)?|look(?:ing)?|turned|toward|towards|orient\w*)\b")
_STOP = re.compile(r"(?:please )?(?:stop|cancel|halt|abort|freeze)(?: (?:the )?(?:robot|task|navigation|now))*")
_BACKUP = re.compile(r"\bback ?up\b|\breverse\b|\bmove back(?:wards?)?\b|\bgo back(?:wards?)?\b|\bbackwards?\b")
_STOPWORD_TEXT = (
    "a an the to of in on at by for with and or please robot you can could would will go move navigate "
    "travel drive head walk over there here me my this that which who whose where is are be it its item "
    "thing object place spot room area containing contains has have some one up near next towards toward "
    "into onto from now then just take bring get find visit reach return come approach let lets us kindly "
    "quickly slowly "
)
_STOPWORDS = frozenset(_STOPWORD_TEXT.split())
_SYNONYMS = {
    "wooden": "wood",
    "timber": "wood",
    "plank": "wood",
    "metal": "steel",
    "metallic": "steel",
    "iron": "steel",
    "drum": "barrel",
    "keg": "barrel",
    "cask": "barrel",
    "fuel": "oil",
    "petrol": "oil",
    "gasoline": "oil",
    "diesel": "oil",
    "loo": "toilet",
    "lavatory": "toilet",
    "wc": "toilet",
    "restroom": "toilet",
    "washroom": "toilet",
    "bathroom": "toilet",
    "crate": "box",
    "chest": "box",
    "carton": "box",
    "store": "hold",
    "contain": "hold",
    "keep": "hold",
}


@dataclass(frozen=True)
class Interpretation:
    """A program (None when the command was not understood) and a one-line message for the user."""

    program: str | None
    message: str

    @property
    def understood(self) -> bool:
        return self.program is not None


def _stem(word: str) -> str:
    word = _SYNONYMS.get(word, word)
    if len(word) > 4 and word.endswith("ies"):
        word = word[:-3] + "y"
    elif len(word) > 4 and word.endswith(("xes", "shes", "ches")):
        word = word[:-2]
    elif len(word) > 3 and word.endswith("s") and not word.endswith("ss"):
        word = word[:-1]
    return _SYNONYMS.get(word, word)


def _tokens(text: str) -> list[str]:
    return [_stem(w) for w in re.findall(r"[a-z]+", text.lower()) if w not in _STOPWORDS]


def _normalise(text: str) -> str:
    text = text.replace("−", "-").replace("’", "'").lower().strip()
    return " ".join(text.split())


class OfflineInterpreter:
    """Rule-based interpreter over a world's named destinations (name, aliases and description words)."""

    def __init__(self, destinations: Iterable[Destination], dock_approach: bool = True) -> None:
        """`dock_approach`: the program's destinations hold 'dock' (in front of the station): drive there first."""
        self.dock_approach = dock_approach
        self.destinations = list(destinations)
        self._phrases: list[tuple[str, Destination]] = []
        for dest in self.destinations:
            for phrase in (dest.name, *dest.aliases):
                self._phrases.append((_normalise(phrase), dest))
        self._phrases.sort(key=lambda item: -len(item[0]))
        self._words: dict[str, set[str]] = {}
        for dest in self.destinations:
            words = set(_tokens(" ".join((dest.name, dest.description, *dest.aliases))))
            self._words[dest.name] = words
        counts: dict[str, int] = {}
        for words in self._words.values():
            for w in words:
                counts[w] = counts.get(w, 0) + 1
        n = max(len(self._words), 1)
        self._weight = {w: 1.0 + math.log(n / c) for w, c in counts.items()}

    # -- public ------------------------------------------------------------------------------------------------
    def interpret(self, text: str) -> Interpretation:
        """Turn one command (possibly a sequence) into a program, or explain that it was not understood."""
        command = _normalise(text)
        if not command:
            return Interpretation(None, "Empty command. " + HELP_TEXT)
        if _NEGATION.search(command):
            return Interpretation(None, f"I do not act on negated commands ({text!r}). " + HELP_TEXT)
        clauses = [c.strip(" ,.!?") for c in _SEQUENCE_SPLIT.split(command)]
        clauses = [c for c in clauses if c]
        if not clauses:
            return Interpretation(None, f"Sorry, I did not understand {text!r}. " + HELP_TEXT)
        lines: list[str] = []
        for clause in clauses:
            code = self._split_on_and(clause) or self._clause(clause)
            if code is None:
                return Interpretation(None, f"Sorry, I did not understand {clause!r}. " + HELP_TEXT)
            lines.append(code)
        comment = "# " + " ".join(text.split()).replace("\n", " ")[:200]
        return Interpretation(comment + "\n" + "\n".join(lines) + "\n", "ok")

    # -- clauses -----------------------------------------------------------------------------------------------
    def _split_on_and(self, clause: str) -> str | None:
        """'undock and go to the crate': two actions, if every part is an action of its own (has a verb or is a
        dock/undock/spin/... command); 'the crate and the barrels' stays one clause (a tour)."""
        parts = [p.strip(" ,.!?") for p in re.split(r",?\s+\band\b\s+", clause) if p.strip(" ,.!?")]
        if len(parts) < 2:
            return None
        codes = []
        for part in parts:
            code = self._clause(part)
            if code is None or (code.startswith("navigator.start") and not _NAV_VERBS.search(part)):
                return None
            codes.append(code)
        return "\n".join(codes)

    def _clause(self, clause: str) -> str | None:
        handlers = (
            self._undock,
            self._coordinates,
            self._named_destination,
            self._dock,
            self._stop,
            self._spin,
            self._backup,
            self._destination,
        )
        for handler in handlers:
            code = handler(clause)
            if code is not None:
                return code
        return None

    def _named_destination(self, clause: str) -> str | None:
        """A destination named exactly, in a clause that asks to go somewhere (beats 'go home' meaning dock)."""
        if not _NAV_VERBS.search(clause) and not any(clause == phrase for phrase, _ in self._phrases):
            return None
        return self._destination(clause, exact_only=True)

    @staticmethod
    def _undock(clause: str) -> str | None:
        if re.search(r"\bun-?dock\w*|\bleave the (?:dock|charger|base)|\bget off the (?:dock|charger)", clause):
            return "navigator.undock()"
        return None

    def _dock(self, clause: str) -> str | None:
        if re.search(
            r"\bdock\w*\b|\bgo home\b|\breturn home\b|\bhome base\b|\bcharg(?:e|er|ing)\b|\brecharge\b|\bback to base\b"
            r"|\bgo back home\b",
            clause,
        ):
            if not self.dock_approach:
                return "navigator.dock()"
            return f"navigator.startToPose({self._pose_expr_by_name(DOCK_DESTINATION, None)})\nnavigator.dock()"
        return None

    @staticmethod
    def _stop(clause: str) -> str | None:
        if _STOP.fullmatch(clause):
            return "navigator.cancelTask()"
        return None

    @staticmethod
    def _spin(clause: str) -> str | None:
        if re.search(r"\bturn around\b|\bface the other way\b|\bu-?turn\b", clause):
            return "navigator.spin(3.1416)"
        m = re.search(r"\b(?:spin|rotate|turn)\b", clause)
        if not m:
            return None
        rest = clause[m.end() :]
        amount = re.search(rf"({_NUMBER})\s*(?:degrees?|deg|°)", rest)
        if amount:
            radians = math.radians(float(amount.group(1)))
        elif re.search(r"\bhalf\b", rest):
            radians = math.pi
        elif re.search(r"\bquarter\b", rest):
            radians = math.pi / 2
        elif m.group(0) == "turn" and not re.search(r"\b(?:full|once|around|circle|360)\b", rest):
            if not re.search(r"\b(?:left|right)\b", rest):
                return None
            radians = math.pi / 2
        else:
            radians = 2 * math.pi
        if re.search(r"\b(?:right|clockwise)\b", rest) and not re.search(r"\bcounter-?clockwise\b", rest):
            radians = -abs(radians)
        return f"navigator.spin({radians:.4f})"

    @staticmethod
    def _backup(clause: str) -> str | None:
        if not re.search(
            r"\bback ?up\b|\breverse\b|\bmove back(?:wards?)?\b|\bgo back(?:wards?)?\b|\bbackwards?\b", clause
        ):
            return None
        if re.search(r"\bback to\b", clause):
            return None
        dist = 0.3
        m = re.search(rf"({_NUMBER})\s*(cm|centimet(?:re|er)s?|m|met(?:re|er)s?)\b", clause)
        if m:
            dist = float(m.group(1)) / (100.0 if m.group(2).startswith("c") else 1.0)
        dist = abs(dist)
        return f"navigator.backup({dist:g}, 0.1)"

    def _coordinates(self, clause: str) -> str | None:
        m = re.search(
            rf"(?:\bx\s*=?\s*)?\(?\s*({_NUMBER})\s*(?:,\s*|\s+)(?:y\s*=?\s*)?({_NUMBER})\s*\)?(?!\s*(?:degrees?|deg|°))",
            clause,
        )
        if not m:
            return None
        x, y = float(m.group(1).replace("+", "")), float(m.group(2).replace("+", ""))
        heading = self._heading(clause[m.end() :]) or "TurtleBot4Directions.NORTH"
        return f"navigator.startToPose(navigator.getPoseStamped([{x!r}, {y!r}], {heading}))"

    @staticmethod
    def _heading(text: str) -> str | None:
        """A heading expression from 'facing east' / 'heading 90 degrees' / a trailing direction word."""
        deg = re.search(rf"({_NUMBER})\s*(?:degrees?|deg|°)", text)
        if deg and _FACING.search(text):
            return repr(float(deg.group(1)))
        for pattern, member in _DIRECTION_WORDS:
            if re.search(pattern, text) and member in DIRECTIONS:
                return f"TurtleBot4Directions.{member}"
        return None

    def _destination(self, clause: str, exact_only: bool = False) -> str | None:
        found: list[tuple[int, Destination]] = []
        taken = [False] * len(clause)
        for phrase, dest in self._phrases:
            for m in re.finditer(rf"(?<![a-z]){re.escape(phrase)}(?![a-z])", clause):
                if any(taken[m.start() : m.end()]):
                    continue
                for i in range(m.start(), m.end()):
                    taken[i] = True
                found.append((m.start(), dest))
        ordered: list[Destination] = []
        for _, dest in sorted(found, key=lambda item: item[0]):
            if not ordered or ordered[-1].name != dest.name:
                ordered.append(dest)
        facing_match = _FACING.search(clause)
        heading = self._heading(clause[facing_match.start() :]) if facing_match else None
        if len(ordered) == 1:
            return self._goto(ordered[0], heading)
        if len(ordered) > 1:
            poses = ", ".join(self._pose_expr(d, None) for d in ordered)
            return f"navigator.startFollowWaypoints([{poses}])"
        if exact_only or not _NAV_VERBS.search(clause):
            return None
        best = self._best_by_words(clause[: facing_match.start()] if facing_match else clause)
        return None if best is None else self._goto(best, heading)

    def _best_by_words(self, clause: str) -> Destination | None:
        words = set(_tokens(clause))
        if not words:
            return None
        scores = []
        for dest in self.destinations:
            score = sum(self._weight.get(w, 0.0) for w in words & self._words[dest.name])
            scores.append((score, dest))
        scores.sort(key=lambda item: -item[0])
        if not scores or scores[0][0] <= 0.0:
            return None
        if len(scores) > 1 and abs(scores[0][0] - scores[1][0]) < 1e-9:
            return None  # a tie: ambiguous, do not guess
        return scores[0][1]

    @staticmethod
    def _pose_expr(dest: Destination, heading: str | None) -> str:
        return OfflineInterpreter._pose_expr_by_name(dest.name, heading)

    @staticmethod
    def _pose_expr_by_name(name: str, heading: str | None) -> str:
        key = repr(name)
        rotation = heading if heading is not None else f"destinations[{key}][2]"
        return f"navigator.getPoseStamped(destinations[{key}][0:2], {rotation})"

    def _goto(self, dest: Destination, heading: str | None) -> str:
        return f"navigator.startToPose({self._pose_expr(dest, heading)})"
