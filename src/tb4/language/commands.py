"""From a command text to robot motion: ask a backend for a program, check it, then run it (or not).

This is the ROS-free heart of gpt_node: the node only moves messages in and out. Whatever the backend (a model or
the offline interpreter), the program goes through the same safe executor; nothing moves unless the whole plan
was accepted and the parking brake is off.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from tb4.language.bounded_format import clip
from tb4.language.limits import DEFAULT_LIMITS, Limits
from tb4.language.model_client import ModelClient, ModelError
from tb4.language.offline import OfflineInterpreter
from tb4.language.plan import plan_program
from tb4.language.prompt import build_messages, extract_program
from tb4.language.run_plan import ExecutionReport, execute_plan
from tb4.language.vocabulary import Plan, PlanningError, ProgramRejected

__all__ = [
    "Backend",
    "BackendAnswer",
    "OfflineBackend",
    "ModelBackend",
    "Prepared",
    "Outcome",
    "CommandProcessor",
]


@dataclass(frozen=True)
class BackendAnswer:
    """A program, or None with a message saying why there is none."""

    program: str | None
    message: str = ""


class Backend(Protocol):
    name: str

    def program_for(self, text: str) -> BackendAnswer: ...


class OfflineBackend:
    """The rule-based interpreter: no key, no network."""

    name = "offline"

    def __init__(self, interpreter: OfflineInterpreter) -> None:
        self.interpreter = interpreter

    def program_for(self, text: str) -> BackendAnswer:
        result = self.interpreter.interpret(text)
        return BackendAnswer(result.program, result.message)


class ModelBackend:
    """A Chat Completions model given our few-shot prompt and the world's destinations."""

    name = "openai"

    def __init__(self, client: ModelClient, destinations: Mapping[str, Sequence[float]]) -> None:
        self.client = client
        self.destinations = destinations

    def program_for(self, text: str) -> BackendAnswer:
        try:
            reply = self.client.complete(build_messages(text, self.destinations))
        except ModelError as exc:
            return BackendAnswer(None, f"model error: {exc}")
        return BackendAnswer(extract_program(reply))


@dataclass(frozen=True)
class Prepared:
    """A checked program waiting to run."""

    text: str
    program: str
    plan: Plan


@dataclass(frozen=True)
class Outcome:
    """What became of a command: status is executed, parked, refused, not_understood, failed or pending.

    `refused`: the program broke a rule or a limit. `failed`: the model could not be asked, the planner itself
    failed (out of memory, an internal error), or the plan stopped on a failed step."""

    status: str
    message: str
    program: str = ""
    plan: Plan | None = None
    report: ExecutionReport | None = None


def _printable(text: str) -> str:
    """Control characters (terminal escapes a model or a publisher could slip in) shown as escapes in logs."""
    return "".join(c if c in "\n\t" or (c.isprintable()) else repr(c)[1:-1] for c in text)


class Logger(Protocol):
    def info(self, msg: str) -> Any: ...

    def warn(self, msg: str) -> Any: ...

    def error(self, msg: str) -> Any: ...


class CommandProcessor:
    """prepare(text) asks the backend and checks the program; run(prepared) executes it unless parked."""

    def __init__(
        self,
        backend: Backend,
        navigator: Any,
        destinations: Mapping[str, Sequence[float]],
        check_pose: Callable[[float, float], str | None] | None,
        logger: Logger,
        parking_brake: bool = True,
        limits: Limits = DEFAULT_LIMITS,
        redact: Callable[[str], str] = lambda s: s,
    ) -> None:
        self.backend = backend
        self.navigator = navigator
        self.destinations = destinations
        self.check_pose = check_pose
        self.log = logger
        self.parking_brake = parking_brake
        self.limits = limits
        self.redact = redact

    def prepare(self, text: str) -> Prepared | Outcome:
        """A checked Prepared program, or an Outcome saying why there is none (nothing has moved either way)."""
        answer = self.backend.program_for(text)
        if answer.program is None:
            message = self.redact(clip(answer.message or "no program", 2 * self.limits.max_message))
            status = "failed" if message.startswith("model error") else "not_understood"
            (self.log.error if status == "failed" else self.log.warn)(message)
            return Outcome(status, message)
        # A model can answer with anything, of any length: what is logged is cut to what a program may be.
        program = _printable(self.redact(clip(answer.program, self.limits.max_chars + 1)))
        self.log.info(f"Program ({self.backend.name}):\n{program.rstrip()}")
        try:
            plan = plan_program(answer.program, self.destinations, self.check_pose, self.limits)
        except ProgramRejected as exc:
            message = self.redact(f"Program refused, nothing was executed: {exc}")
            self.log.error(message)
            return Outcome("refused", message, program)
        except PlanningError as exc:
            message = self.redact(f"Planning failed ({exc.kind}), nothing was executed: {exc.detail}")
            self.log.error(message)
            return Outcome("failed", message, program)
        return Prepared(text, program, plan)

    def run(self, prepared: Prepared, stop: threading.Event | None = None) -> Outcome:
        """Execute a prepared plan unless parked; setting `stop` (from any thread) ends it early."""
        if self.parking_brake:
            message = f"Parking brake is on: not executing ({prepared.plan.describe()})"
            self.log.warn(message)
            return Outcome("parked", message, prepared.program, prepared.plan)
        self.log.info(f"Executing: {prepared.plan.describe()}")
        try:
            report = execute_plan(prepared.plan, self.navigator, self.limits, stop=stop)
        except Exception as exc:  # noqa: BLE001 - a navigator failure must not kill the node
            message = self.redact(clip(f"Execution failed: {type(exc).__name__}: {exc}", self.limits.max_message))
            self.log.error(message)
            return Outcome("failed", message, prepared.program, prepared.plan)
        if report.stopped:
            message = f"Stopped after {report.completed}/{report.total} steps: {report.stopped}"
            self.log.warn(message)
            return Outcome("failed", message, prepared.program, prepared.plan, report)
        message = f"Done ({report.completed} steps)"
        self.log.info(message)
        return Outcome("executed", message, prepared.program, prepared.plan, report)

    def handle(self, text: str, stop: threading.Event | None = None) -> Outcome:
        """prepare + run in one go."""
        prepared = self.prepare(text)
        if isinstance(prepared, Outcome):
            return prepared
        return self.run(prepared, stop)
