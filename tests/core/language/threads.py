"""Run one piece of work on several threads at once and collect what each raised (thread-safety tests)."""

from __future__ import annotations

import threading
from collections.abc import Callable


def errors_in_threads(work: Callable[[], object], threads: int, join_timeout: float = 60.0) -> list[BaseException]:
    """`work` on `threads` threads released together (a barrier); every exception any of them raised."""
    together = threading.Barrier(threads)
    errors: list[BaseException] = []

    def run() -> None:
        try:
            together.wait(10)
            work()
        except BaseException as exc:  # noqa: BLE001 - reported to the test, whatever it is
            errors.append(exc)

    started = [threading.Thread(target=run) for _ in range(threads)]
    for thread in started:
        thread.start()
    for thread in started:
        thread.join(join_timeout)
    assert not any(thread.is_alive() for thread in started), f"a thread still runs after {join_timeout:g} s"
    return errors
