"""Which executor spins the navigator's node, and that whatever a user adds to that node still runs on it.

The navigator spins with rclpy's EventsExecutor where that executor runs everything a user may attach (Kilted's
rclpy; Jazzy's from 7.1.11), else with a SingleThreadedExecutor; TB4_NAVIGATOR_EXECUTOR chooses one. This runs in
both test stages, so each choice is exercised over DDS on the rclpy it is meant for.
"""

from __future__ import annotations

import importlib.metadata
import itertools

import pytest
from std_msgs.msg import String

from tb4.core.waits import wait_until
from tb4.navigator.basic_navigator import BasicNavigator
from tb4.ros.background import EXECUTOR_ENV, events_executor_complete

_names = itertools.count()


@pytest.mark.parametrize(
    ("version", "complete"),
    [("7.1.5", False), ("7.1.11", True), ("7.2.0", True), ("9.1.2", True), ("10.0.1", True), ("3.3.14", False)],
)
def test_the_events_executor_counts_as_complete_from_the_releases_that_await_async_callbacks(
    monkeypatch: pytest.MonkeyPatch, version: str, complete: bool
) -> None:
    monkeypatch.setattr(importlib.metadata, "version", lambda name: version)
    events_executor_complete.cache_clear()
    try:
        assert events_executor_complete() is complete
    finally:
        events_executor_complete.cache_clear()


def test_an_unreadable_rclpy_version_keeps_the_single_threaded_executor(monkeypatch: pytest.MonkeyPatch) -> None:
    def missing(name: str) -> str:
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", missing)
    events_executor_complete.cache_clear()
    try:
        assert events_executor_complete() is False
    finally:
        events_executor_complete.cache_clear()


@pytest.mark.parametrize("choice", ["", "auto", "single", "events"])
# an EventsExecutor of an rclpy before the complete ones drops an async callback's coroutine unawaited; where it
# awaits them the test asserts that the callback ran
@pytest.mark.filterwarnings("ignore:coroutine '.*on_message_async' was never awaited:RuntimeWarning")
def test_a_users_callbacks_on_the_navigators_node_run_with_each_executor(
    monkeypatch: pytest.MonkeyPatch, navigators: list[BasicNavigator], choice: str
) -> None:
    from rclpy.executors import SingleThreadedExecutor

    monkeypatch.setenv(EXECUTOR_ENV, choice)
    nav = BasicNavigator(node_name=f"executor_probe_{next(_names)}")
    navigators.append(nav)
    events = choice == "events" or (choice in ("", "auto") and events_executor_complete())
    assert isinstance(nav._spinner.executor, SingleThreadedExecutor) is not events

    plain: list[str] = []
    awaited: list[str] = []

    async def on_message_async(msg: String) -> None:
        awaited.append(msg.data)

    topic = f"{nav.get_name()}_topic"
    nav.create_subscription(String, topic, plain.append, 10)  # as a user's script adds to the navigator's node
    nav.create_subscription(String, topic, on_message_async, 10)
    publisher = nav.create_publisher(String, topic, 10)

    def both_heard() -> bool:
        publisher.publish(String(data="hello"))
        # the EventsExecutor of an rclpy before the complete ones never runs an async callback (chosen by hand only)
        return bool(plain) and (bool(awaited) or (events and not events_executor_complete()))

    assert wait_until(both_heard, 15.0, period=0.1), f"plain callback ran {len(plain)}, async {len(awaited)} times"


def test_an_unknown_executor_choice_is_refused_with_the_choices(
    monkeypatch: pytest.MonkeyPatch, navigators: list[BasicNavigator]
) -> None:
    monkeypatch.setenv(EXECUTOR_ENV, "turbo")
    with pytest.raises(ValueError, match=r"TB4_NAVIGATOR_EXECUTOR='turbo'.*auto, events, single"):
        BasicNavigator(node_name=f"executor_refused_{next(_names)}")
