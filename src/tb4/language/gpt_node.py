"""gpt_node: typed commands in on `user_input`, robot programs out through the safe executor.

Upstream-compatible surface: node `gpt_node`; parameters openai_api_key, model_name (default: $TB4_LLM_MODEL, else
DEFAULT_MODEL), parking_brake (true = log the program, do not run it); sub `user_input` (std_msgs/String), pub
`ready_for_input` (std_msgs/Bool). Ours on top: base_url, backend (offline / openai; openai when a key (parameter or
OPENAI_API_KEY) or a base_url is given, else offline), destinations_file (the site's named places and map, see
site.py: what a real robot uses) or else world (a simulator world's), timeout, max_retries, and hardening for
shared networks: allowed_publisher (only that node's commands are accepted) and require_confirmation (a program
runs only after a 'yes' on user_input).

Commands are handled one at a time by a worker thread; the subscription callback only queues, so the node keeps
answering (and publishing ready_for_input) while it plans and while the robot drives. Planning has a deadline
(CPU time, with a wall-clock backstop) and memory bounds (see limits.py), so no program keeps the worker; a command
that arrives while it is busy is dropped with a warning that says so, and ready_for_input reads false until the
worker is free again.
The API key parameter is read once and then blanked, so it cannot be read back through the parameter services;
it never reaches a log line.
"""

from __future__ import annotations

import os
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Any

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Bool, String

from tb4.language.bounded_format import clip
from tb4.language.commands import (
    Backend,
    CommandProcessor,
    ModelBackend,
    OfflineBackend,
    Outcome,
    Prepared,
)
from tb4.language.limits import DEFAULT_LIMITS
from tb4.language.model_client import ModelClient, ModelError, ModelSettings, default_model, redact
from tb4.language.offline import OfflineInterpreter
from tb4.language.site import Site, load_site
from tb4.language.world_context import DOCK_DESTINATION, destination_table, pose_checker

__all__ = ["GptNode", "GptNodeOptions", "CONFIRM_WORDS", "CANCEL_WORDS"]

CONFIRM_WORDS = frozenset({"yes", "y", "confirm", "ok", "go", "go ahead", "do it"})
CANCEL_WORDS = frozenset({"no", "n", "cancel", "abort", "stop"})
_CONFIRM_SECONDS = 120.0
READY_ACK_WAIT = 2.0  # s shutdown waits for every reader to acknowledge the last ready_for_input


@dataclass(frozen=True)
class GptNodeOptions:
    """Parameter defaults (each is also a ROS parameter of the node, which overrides it)."""

    openai_api_key: str = ""
    model_name: str = field(default_factory=default_model)
    parking_brake: bool = True
    base_url: str = ""
    backend: str = ""
    world: str = "depot"  # used when destinations_file is empty
    destinations_file: str = ""
    allowed_publisher: str = ""
    require_confirmation: bool = False
    timeout: float = 30.0
    max_retries: int = 2

    def __repr__(self) -> str:  # the key must never be printed
        fields = ", ".join(
            f"{k}={('***' if k == 'openai_api_key' and v else repr(v))}" for k, v in self.__dict__.items()
        )
        return f"GptNodeOptions({fields})"


class GptNode(Node):
    """The language node. `navigator` is a TurtleBot4Navigator, or anything with its API: getPoseStamped, goToPose,
    goThroughPoses, followWaypoints, spin, backup, driveOnHeading, isTaskComplete, getResult, cancelTask, dock, undock
    and the log calls (see run_plan.py)."""

    def __init__(self, navigator: Any, options: GptNodeOptions = GptNodeOptions(), namespace: str = "", **kw: Any):
        super().__init__("gpt_node", namespace=namespace, **kw)
        p = {name: self.declare_parameter(name, getattr(options, name)).value for name in options.__dict__}
        key = str(p["openai_api_key"] or "")
        if key:  # blank it: parameter services would otherwise hand it to anyone on the network
            self.set_parameters([Parameter("openai_api_key", Parameter.Type.STRING, "")])
        self._secrets = tuple(s for s in (key, os.environ.get("OPENAI_API_KEY", "")) if s)
        self.parking_brake = bool(p["parking_brake"])
        self.allowed_publisher = str(p["allowed_publisher"] or "").strip()
        self.require_confirmation = bool(p["require_confirmation"])
        site = load_site(str(p["destinations_file"] or ""), str(p["world"] or ""))
        destinations = destination_table(site)
        backend = self._make_backend(p, key, site, destinations)
        self.processor = CommandProcessor(
            backend,
            navigator,
            destinations,
            pose_checker(site),
            self,
            parking_brake=self.parking_brake,
            limits=DEFAULT_LIMITS,
            redact=self.redact,
        )
        self.outcomes: list[Outcome] = []
        self._pending: tuple[Prepared, float] | None = None
        self._busy = threading.Event()
        self._stop = threading.Event()  # the worker ends
        self._cancel = threading.Event()  # the running plan ends (the worker cancels its task itself)
        self._queue: queue.Queue[str] = queue.Queue(maxsize=1)
        self._done = threading.Condition()
        self.ready_pub = self.create_publisher(Bool, "ready_for_input", 10)
        self.create_subscription(String, "user_input", self._on_input, 10)
        self.create_timer(1.0, self._publish_ready)
        self._worker = threading.Thread(target=self._work, name="gpt_node-worker", daemon=True)
        self._worker.start()
        brake = "ON (programs are logged, not run)" if self.parking_brake else "off (programs run)"
        self.info(
            f"gpt_node ready: backend {backend.name}, site {site.name} "
            f"({', '.join(destinations) or 'no destinations'}), parking brake {brake}"
        )
        self._publish_ready()

    # -- logging (the processor logs through these) --------------------------------------------------------------
    def redact(self, text: str) -> str:
        return redact(text, self._secrets)

    def info(self, msg: str) -> None:
        self.get_logger().info(self.redact(msg))

    def warn(self, msg: str) -> None:
        self.get_logger().warning(self.redact(msg))

    def error(self, msg: str) -> None:
        self.get_logger().error(self.redact(msg))

    # -- set-up ----------------------------------------------------------------------------------------------------
    def _make_backend(self, p: dict[str, Any], key: str, site: Site, destinations: dict) -> Backend:
        choice = str(p["backend"] or "").strip().lower()
        if not choice:
            has_key = bool(key or os.environ.get("OPENAI_API_KEY"))
            choice = "openai" if (has_key or p["base_url"]) else "offline"
        if choice == "offline":
            return OfflineBackend(OfflineInterpreter(site.destinations.values(), DOCK_DESTINATION in destinations))
        if choice != "openai":
            raise ValueError(f"backend must be 'offline' or 'openai', got {choice!r}")
        settings = ModelSettings(
            model=str(p["model_name"]),
            base_url=str(p["base_url"] or ""),
            api_key=key,
            timeout=float(p["timeout"]),
            max_retries=int(p["max_retries"]),
        )
        try:
            return ModelBackend(ModelClient(settings), destinations)
        except ModelError as exc:
            raise ValueError(self.redact(str(exc))) from None

    # -- topics ----------------------------------------------------------------------------------------------------
    @property
    def ready(self) -> bool:
        return not self._busy.is_set()

    def _publish_ready(self) -> None:
        self.ready_pub.publish(Bool(data=self.ready))

    def _publisher_name(self, info: Any) -> str | None:
        """Full name of the node that published a message, from its publisher GID; None if unknown."""
        gid = (info or {}).get("publisher_gid") if isinstance(info, dict) else None
        if not gid:
            return None
        data = list(gid.get("data", b"")) if isinstance(gid, dict) else list(gid)
        if not data:
            return None
        topic = self.resolve_topic_name("user_input")
        for endpoint in self.get_publishers_info_by_topic(topic):
            if list(endpoint.endpoint_gid)[: len(data)] == data[: len(endpoint.endpoint_gid)]:
                ns = endpoint.node_namespace.rstrip("/")
                return f"{ns}/{endpoint.node_name}"
        return None

    def _allowed(self, info: Any) -> tuple[bool, str]:
        if not self.allowed_publisher:
            return True, ""
        who = self._publisher_name(info)
        want = self.allowed_publisher if self.allowed_publisher.startswith("/") else "/" + self.allowed_publisher
        return who == want, who or "an unknown publisher"

    def _on_input(self, msg: String, info: Any) -> None:  # two parameters: rclpy then passes MessageInfo
        text = " ".join(str(msg.data).split())[:1000]
        ok, who = self._allowed(info)
        if not ok:
            self.warn(f"Ignoring a command from {who}: only {self.allowed_publisher} may command this robot")
            return
        if not text:
            return
        if self._busy.is_set():
            self.warn(
                f"Busy with the previous command: dropped {clip(text, 80)!r}; "
                "send it again when ready_for_input is true"
            )
            self._publish_ready()  # tell the sender at once: not ready
            return
        self._busy.set()
        self._publish_ready()
        try:
            self._queue.put_nowait(text)
        except queue.Full:
            self.warn(f"Busy: dropped {clip(text, 80)!r}; send it again when ready_for_input is true")

    # -- work ------------------------------------------------------------------------------------------------------
    def _work(self) -> None:
        while not self._stop.is_set():
            try:
                text = self._queue.get(timeout=0.2)
            except queue.Empty:
                continue
            try:
                outcome = self._handle(text)
            except Exception as exc:  # noqa: BLE001 - the node must keep answering whatever happens
                why = clip(f"{type(exc).__name__}: {exc}", DEFAULT_LIMITS.max_message)
                outcome = Outcome("failed", self.redact(why))
                self.error(f"Command failed: {outcome.message}")
            self._busy.clear()
            self._publish_ready()  # before the outcome counts: with --max-commands the node ends once it does
            with self._done:
                self.outcomes.append(outcome)
                self._done.notify_all()

    def _handle(self, text: str) -> Outcome:
        self.info(f"Command: {text!r}")
        if self._pending is not None:
            prepared, since = self._pending
            self._pending = None
            word = text.lower().strip(" .!")
            if time.monotonic() - since <= _CONFIRM_SECONDS and word in CONFIRM_WORDS:
                return self.processor.run(prepared, self._cancel)
            if word in CANCEL_WORDS:
                self.info("Pending program discarded.")
                return Outcome("cancelled", "pending program discarded", prepared.program, prepared.plan)
            self.info("Pending program discarded (not confirmed); handling the new command.")
        prepared_or_outcome = self.processor.prepare(text)
        if isinstance(prepared_or_outcome, Outcome):
            return prepared_or_outcome
        if self.require_confirmation and not self.parking_brake:
            self._pending = (prepared_or_outcome, time.monotonic())
            message = f"Confirm with 'yes' on user_input to run: {prepared_or_outcome.plan.describe()}"
            self.warn(message)
            return Outcome("pending", message, prepared_or_outcome.program, prepared_or_outcome.plan)
        return self.processor.run(prepared_or_outcome, self._cancel)

    def wait_for_outcomes(self, count: int, timeout: float) -> bool:
        """Block until `count` commands have been handled (for tests and --max-commands)."""
        deadline = time.monotonic() + timeout
        with self._done:
            while len(self.outcomes) < count:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._done.wait(min(remaining, 0.5))
        return True

    def shutdown(self) -> None:
        """Stop the worker and destroy the node. A running plan is asked to stop: the worker thread, the only one
        that talks to the navigator, cancels the robot's current task itself (rclpy does not promise that a
        goal handle tolerates a cancel from another thread while a call on it blocks)."""
        self._cancel.set()
        self._stop.set()
        self._worker.join(timeout=10.0)
        if self._worker.is_alive():
            self.warn("the command worker did not stop within 10 s (a blocking dock or undock?)")
        # the last ready_for_input (true) must reach its readers before the node goes: reliable, so wait for acks
        self.ready_pub.wait_for_all_acked(Duration(seconds=READY_ACK_WAIT))
        self.destroy_node()
