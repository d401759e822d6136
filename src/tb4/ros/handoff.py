"""Work handed to one thread by others: the simulator loop and the viewer's spin thread each own state that only
their thread may touch, and other threads ask them to run a function there and wait for its result."""

from __future__ import annotations

import contextlib
import queue
from collections.abc import Callable
from concurrent.futures import Future
from contextlib import AbstractContextManager
from typing import Any, TypeVar

__all__ = ["Handoff"]

T = TypeVar("T")


class Handoff:
    """`submit(fn)` from any thread returns a Future; the owning thread calls `run_pending()` to run what is
    queued; `close(exc)` fails what is still queued with `exc` and every later submit with `refusal`."""

    def __init__(self, refusal: Callable[[], BaseException]) -> None:
        self._refusal = refusal
        self._queue: queue.SimpleQueue[tuple[Callable[[], Any], Future]] = queue.SimpleQueue()
        self._closed = False

    def submit(self, fn: Callable[[], T]) -> Future:
        future: Future = Future()
        if self._closed:
            future.set_exception(self._refusal())
        else:
            self._queue.put((fn, future))
        return future

    def run_pending(self, guard: AbstractContextManager[Any] | None = None) -> None:
        """Run everything queued now, each under `guard` (e.g. a lock); an exception goes to its caller."""
        while True:
            try:
                fn, future = self._queue.get_nowait()
            except queue.Empty:
                return
            if not future.set_running_or_notify_cancel():
                continue
            try:
                with guard if guard is not None else contextlib.nullcontext():
                    result = fn()
            except BaseException as exc:  # the caller gets it; the owning thread goes on
                future.set_exception(exc)
            else:
                future.set_result(result)

    def close(self, exc: BaseException) -> None:
        """Nobody will run what is still queued: fail it with `exc`, and refuse what comes later."""
        self._closed = True
        while True:
            try:
                _, future = self._queue.get_nowait()
            except queue.Empty:
                return
            if future.set_running_or_notify_cancel():
                future.set_exception(exc)
