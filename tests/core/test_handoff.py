"""Work handed to the simulator loop or the viewer's spin thread: results and errors reach the caller, and work
that can no longer run fails instead of hanging."""

from __future__ import annotations

import threading

import pytest

pytestmark = pytest.mark.core

Handoff = pytest.importorskip("tb4.ros.handoff").Handoff


def test_the_owning_thread_runs_what_others_submit() -> None:
    handoff = Handoff(lambda: RuntimeError("stopped"))
    ok = handoff.submit(lambda: 42)
    bad = handoff.submit(lambda: 1 / 0)
    lock = threading.Lock()
    handoff.run_pending(guard=lock)
    assert ok.result(timeout=1) == 42
    with pytest.raises(ZeroDivisionError):
        bad.result(timeout=1)


def test_closing_fails_queued_work_and_refuses_more() -> None:
    handoff = Handoff(lambda: RuntimeError("refused: stopped"))
    queued = handoff.submit(lambda: 1)
    handoff.close(RuntimeError("never ran"))
    with pytest.raises(RuntimeError, match="never ran"):
        queued.result(timeout=1)
    with pytest.raises(RuntimeError, match="refused"):
        handoff.submit(lambda: 2).result(timeout=1)
