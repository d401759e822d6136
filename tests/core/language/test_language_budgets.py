"""Budgets: no program, however small, makes planning slow, large or chatty.

The programs here are what an attacker would send after reading the executor: values that are small per list but
huge through sharing, formatting bombs in every place a value is shown (log calls, f-strings, refusal reasons),
deep nesting, giant literals, and programs Python's compiler itself refuses. Each must end in a clean refusal
within 1 s of wall time and under 50 MB of extra memory, with a reason of a few hundred characters at most.
(The 1 s / 50 MB figures are the safety property of the issue, asserted with a wide margin: a refusal typically
takes milliseconds and well under 5 MB; bench/bench_language.py measures them.)
"""

from __future__ import annotations

import ast
import gc
import threading
import time
import tracemalloc

import pytest
from test_language_executor import HOSTILE
from threads import errors_in_threads

from tb4.language.bounded_format import bounded_repr, bounded_text, format_value
from tb4.language.executor import Limits, PlanningError, ProgramRejected, plan_program

MAX_REASON = 400


def chain(levels: int, width: int = 4, open_: str = "[", close: str = "]", base: str = "[1, 2, 3, 4]") -> str:
    """A0 = base; A1 = [A0, A0, A0, A0]; ...: tiny lists, 4**levels leaves."""
    lines = [f"A0 = {base}"]
    for i in range(1, levels + 1):
        lines.append(f"A{i} = {open_}" + ", ".join([f"A{i - 1}"] * width) + close)
    return "\n".join(lines) + "\n"


def dict_chain(levels: int) -> str:
    lines = ["A0 = {'a': 1}"]
    for i in range(1, levels + 1):
        lines.append(f"A{i} = {{'a': A{i - 1}, 'b': A{i - 1}, 'c': A{i - 1}, 'd': A{i - 1}}}")
    return "\n".join(lines) + "\n"


def folded(leaves: int) -> str:
    """A balanced sum of 'a'*4096 terms: CPython's compiler folds these constants (4096 characters each)."""
    if leaves == 1:
        return "'a' * 4096"
    return f"({folded(leaves // 2)} + {folded(leaves - leaves // 2)})"


L200 = "L = [" + ", ".join("0" for _ in range(200)) + "]\n"
S490 = "S = '" + "x" * 490 + "'\n"

# (id, program): all must be refused.
BOMBS: list[tuple[str, str]] = [
    # The issue's 560-character program and its sinks: every place a value is formatted.
    ("shared-info", chain(20) + "navigator.info(A20)"),
    ("shared-fstring", chain(20) + "m = f'{A20}'"),
    ("shared-unknown-destination", chain(20) + "x = destinations[A20]"),
    ("shared-pose-position", chain(20) + "p = navigator.getPoseStamped(A20, 0)"),
    ("shared-pose-rotation", chain(20) + "p = navigator.getPoseStamped([0.0, 0.0], A20)"),
    ("shared-bounds-message", chain(20) + "navigator.spin(A20)"),
    ("shared-keyword-bounds", chain(20) + "navigator.backup(backup_speed=A20)"),
    ("shared-key-not-found", chain(20) + "d = {'a': 1}\nx = d[A20]"),
    ("shared-compare", chain(20) + "x = A20 == A20"),
    ("shared-concat", chain(20) + "x = A20 + A20"),
    ("shared-goal-list", chain(20) + "navigator.startFollowWaypoints(A20)"),
    ("shared-tuples", chain(20, open_="(", close=")", base="(1, 2, 3, 4)") + "navigator.info(A20)"),
    ("shared-dicts", dict_chain(20) + "navigator.info(A20)"),
    ("shared-wide", chain(4, width=40) + "navigator.info(A4)"),
    ("shared-strings", S490 + "T = [" + ", ".join(["S"] * 20) + "]\nnavigator.info(T)"),
    ("shared-unpack", chain(20) + "a, b = [A19, A20]\nnavigator.info(b)"),
    ("shared-through-comprehension", L200 + chain(3) + "x = [A3 for i in L]\nnavigator.info(x)"),
    ("shared-through-slices", chain(20) + "x = A20[0:4]\nnavigator.info(x)"),
    ("shared-fstring-in-comprehension", L200 + S490 + "x = [f'{S}' for i in L]"),
    ("deep-value-nesting", "A0 = 1\n" + "".join(f"A{i} = [A{i - 1}]\n" for i in range(1, 20)) + "navigator.info(A19)"),
    # Work and time.
    ("nested-comprehension-work", L200 + "x = [[0 for a in L] for b in L]"),
    ("comprehension-chain-work", L200 + "".join(f"x{i} = [i + 1 for i in L]\n" for i in range(39))),
    ("comprehension-filter-work", L200 + "x = [[[a for a in L if a > 0] for b in L] for c in L]"),
    # Giant literals and deep syntax.
    ("giant-int-literal", "x = " + "9" * 3990),
    ("giant-float-literal", "x = " + "9" * 3000 + ".0"),
    ("giant-string-literal", "x = '" + "a" * 3900 + "'"),
    ("giant-list-literal", "x = [" + "0," * 1900 + "]"),
    ("giant-dict-literal", "x = {" + ", ".join(f"{i}: 0" for i in range(250)) + "}"),
    ("deep-parentheses", "x = " + "(" * 1990 + "1" + ")" * 1990),
    ("deep-unary", "x = " + "-" * 3990 + "1"),
    ("long-sum", "x = " + "+".join(["1"] * 1990)),
    ("long-string-sum", "x = " + "+".join(["'aaaaaaaaaa'"] * 300)),
    ("deep-subscript", "x = L" + "[0]" * 1300),
    ("deep-lambdas", "x = " + "lambda: " * 490 + "1"),
    ("string-growth", S490 + "T = S + S"),
    ("fstring-growth", S490 + "T = f'{S}{S}'"),
    ("fstring-of-list", L200 + "T = f'{L}{L}{L}'"),
    ("compile-time-folding", "x = " + folded(100)),
    (
        "many-goals-through-comprehension",
        L200 + "navigator.startFollowWaypoints([navigator.getPoseStamped([1.0, 1.0], 0) for i in L])",
    ),
    ("dict-key-bomb", chain(20) + "d = {A20: 1}"),
    ("log-flood", "".join(f"navigator.info('{i}' + '" + "x" * 80 + "')\n" for i in range(40))),
    # The language Python accepts, no more.
    ("repeated-keyword", "navigator.spin(spin_dist=1.0, spin_dist=2.0)"),
    ("repeated-keyword-msg", "navigator.info(msg='a', msg='b')"),
    ("repeated-keyword-pose", "p = navigator.getPoseStamped(position=[0.0, 0.0], position=[1.0, 1.0])"),
    ("positional-and-keyword", "navigator.spin(1.0, spin_dist=2.0)"),
    ("keyword-before-positional", "navigator.spin(spin_dist=1.0, 2.0)"),
    ("await-outside-function", "await navigator.dock()"),
    ("yield-outside-function", "x = yield 1"),
    ("return-outside-function", "return 1"),
    ("break-outside-loop", "break"),
    ("continue-outside-loop", "continue"),
    ("nonlocal-at-module-level", "nonlocal x"),
    ("assign-to-debug", "__debug__ = 1"),
    ("assign-to-literal", "1 = x"),
    ("starred-assignment-twice", "*a, *b = [1, 2]"),
    ("invalid-fstring", "x = f'{'"),
    ("fstring-conversion-bomb", chain(20) + "x = f'{A20!r}'"),
    ("fstring-format-spec", "x = f'{1:>1000000}'"),
    ("bad-escape", "x = '\\N{NO SUCH NAME}'"),
    ("tab-space-mix", "x = 1\n\ty = 2"),
    ("non-utf8-surrogate", "x = '\\udcff' + 1"),
]


def _refuse(program: str, context: tuple | None = None) -> tuple[ProgramRejected, float, int]:
    """(refusal, seconds, peak bytes). The time is this thread's CPU time: on a machine shared by many jobs a
    thread can wait for a core longer than the work takes, which says nothing about the planner. The wall time
    is bounded by design (the planning deadline, tested below) and checked here with a wider margin."""
    table, check = context or ({"wood crate": [0.0, 3.0, 0.0]}, None)
    tracemalloc.start()
    started, started_cpu = time.monotonic(), time.thread_time()
    try:
        with pytest.raises(ProgramRejected) as info:
            plan_program(program, table, check)
        cpu = time.thread_time() - started_cpu
        _size, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert time.monotonic() - started < 5.0, "refusing took more than 5 s of wall time"
    return info.value, cpu, peak


@pytest.mark.parametrize("program", [p for _, p in BOMBS + HOSTILE], ids=[i for i, _ in BOMBS + HOSTILE])
def test_hostile_program_is_refused_quickly_small_and_briefly(program, depot_context) -> None:
    refusal, elapsed, peak = _refuse(program, depot_context)
    assert elapsed < 1.0, f"refusing took {elapsed:.2f} s"
    assert peak < 50e6, f"refusing took {peak / 1e6:.1f} MB"
    assert 0 < len(str(refusal)) <= MAX_REASON, f"reason of {len(str(refusal))} characters"
    assert "\n" not in refusal.reason


def test_the_issues_program_is_560_characters_or_less_and_refused_by_the_size_budget() -> None:
    program = chain(20) + "navigator.info(A20)"
    assert len(program) <= 560
    refusal, _elapsed, _peak = _refuse(program)
    assert "value too large" in refusal.reason and refusal.line <= 8


def test_a_value_just_under_the_budget_is_refused_with_a_bounded_reason() -> None:
    """A4 (1365 cells) passes every check; its refusal message must still be short."""
    refusal, _elapsed, _peak = _refuse(chain(4) + "x = destinations[A4]")
    assert refusal.reason.startswith("unknown destination [[[[[1, 2, 3, 4], [1, 2, 3, 4]")
    assert "…" in refusal.reason and len(refusal.reason) <= 300
    plan = plan_program(chain(4) + "navigator.info(A4)")
    assert len(plan.steps[0].args[0]) <= Limits().max_string


def test_repeated_keyword_is_refused_as_python_refuses_it() -> None:
    with pytest.raises(SyntaxError, match="keyword argument repeated"):
        compile("navigator.spin(spin_dist=1.0, spin_dist=2.0)", "<p>", "exec")
    with pytest.raises(ProgramRejected, match="keyword argument repeated") as info:
        plan_program("navigator.info('ok')\nnavigator.spin(spin_dist=1.0, spin_dist=2.0)")
    assert info.value.line == 2


#: a deadline no planning run here reaches, for the calls that test something else: the default (0.5 s of wall
#: time) is met by a second or two of CPU on a quiet machine, not on one shared by many jobs (a stress run's
#: worker waited past it for a core)
NO_DEADLINE = 60.0


def test_the_planning_deadline_refuses_slow_programs() -> None:
    program = L200 + "".join(f"x{i} = [i + 1 for i in L]\n" for i in range(10))
    plan_program(program, limits=Limits(max_eval_ops=10**9, max_plan_seconds=NO_DEADLINE))  # a valid program
    with pytest.raises(ProgramRejected, match=r"planning took longer than 1e-06 s"):
        plan_program(program, limits=Limits(max_eval_ops=10**9, max_plan_seconds=1e-6))


def test_a_slow_pose_check_counts_against_the_wall_clock_backstop() -> None:
    def slow(x: float, y: float) -> None:
        time.sleep(0.05)

    program = "navigator.startToPose(navigator.getPoseStamped([1.0, 1.0], 0))\n" * 10
    started = time.monotonic()
    with pytest.raises(ProgramRejected, match=r"planning took longer than 0.2 s of wall time"):
        plan_program(program, check_pose=slow, limits=Limits(max_plan_wall_seconds=0.2))
    assert time.monotonic() - started < 5.0


def test_waiting_does_not_count_against_the_cpu_deadline() -> None:
    """The deadline is the planning thread's CPU time: a plan that waits (for a core on a busy machine, here for a
    pose check) past max_plan_seconds of wall time is still planned (stress run s29: a valid program refused under
    load). The CPU a program costs is still bounded (test_the_planning_deadline_refuses_slow_programs)."""

    def waits(x: float, y: float) -> None:
        time.sleep(0.05)

    program = "navigator.startToPose(navigator.getPoseStamped([1.0, 1.0], 0))\n" * 10
    started = time.monotonic()
    plan = plan_program(program, check_pose=waits, limits=Limits(max_plan_seconds=0.2))
    assert time.monotonic() - started > 0.4  # waited more than twice the deadline in wall time
    assert len(plan.steps) == 10


def test_the_deadline_is_this_threads_cpu_time_not_other_threads() -> None:
    """Sixteen threads planning at once (one core's worth of Python between them) each get the CPU budget of
    their own thread: a plan well within its budget passes although its wall time is many times its CPU time (a
    wall-clock deadline refused such plans: stress run s29, test_planning_is_thread_safe_and_independent). The
    margin is wide: a thread's CPU time for the same plan grows when it shares the interpreter (2-3x seen)."""
    program = L200 + "".join(f"x{i} = [i + 1 for i in L]\n" for i in range(10))
    alone = 0.0
    for _ in range(2):
        start = time.thread_time()
        plan_program(program, limits=Limits(max_eval_ops=10**9, max_plan_seconds=NO_DEADLINE))
        alone = max(alone, time.thread_time() - start)
    # the wall-clock backstop off: sixteen threads on a loaded machine can take longer than it (stress run s31)
    limits = Limits(max_eval_ops=10**9, max_plan_seconds=6.0 * alone, max_plan_wall_seconds=NO_DEADLINE)
    # A garbage collection is charged to the thread whose allocation set it off, and a full one walks every object
    # this pytest worker holds after hundreds of tests: the likely cause of one thread over 6x in a make test run
    # (three workers), as load alone gave at most 1.4x. The objects held so far are left out of collections.
    gc.collect()
    gc.freeze()
    try:
        errors = errors_in_threads(lambda: plan_program(program, limits=limits), 16)
    finally:
        gc.unfreeze()
    assert not errors, errors


def test_programs_are_parsed_one_at_a_time_across_threads(monkeypatch) -> None:
    """CPython 3.11's ast.parse is not safe in two threads at once (a shared recursion counter: stress run s44 saw
    "SystemError in the planner" in one of sixteen planning threads). The parse here takes 5 ms, so without the
    planner's lock the sixteen threads would overlap in it."""
    real_parse = ast.parse
    inside = 0
    most_inside = 0
    lock = threading.Lock()

    def slow_parse(*args, **kwargs):
        nonlocal inside, most_inside
        with lock:
            inside += 1
            most_inside = max(most_inside, inside)
        try:
            time.sleep(0.005)
            return real_parse(*args, **kwargs)
        finally:
            with lock:
                inside -= 1

    monkeypatch.setattr(ast, "parse", slow_parse)
    limits = Limits(max_plan_seconds=NO_DEADLINE, max_plan_wall_seconds=NO_DEADLINE)
    errors = errors_in_threads(lambda: plan_program("x = 1\nnavigator.info(x)", limits=limits), 16)
    assert not errors, errors
    assert most_inside == 1


def test_the_total_allocation_bound_refuses_programs_that_build_too_much() -> None:
    program = L200 + "".join(f"x{i} = L[0:200]\n" for i in range(20))
    plan_program(program, limits=Limits(max_plan_seconds=NO_DEADLINE))
    with pytest.raises(ProgramRejected, match="builds too much data"):
        plan_program(program, limits=Limits(max_total_cells=2000, max_plan_seconds=NO_DEADLINE))


@pytest.mark.parametrize(
    ("error", "kind"),
    [(MemoryError, "out of memory"), (RecursionError, "recursion limit"), (KeyError, "internal error")],
)
def test_planner_failures_are_reported_as_what_they_are_not_as_refusals(error, kind) -> None:
    def broken(x: float, y: float) -> None:
        raise error("boom")

    with pytest.raises(PlanningError) as info:
        plan_program("navigator.startToPose(navigator.getPoseStamped([1.0, 1.0], 0))", check_pose=broken)
    assert not isinstance(info.value, ProgramRejected)
    assert info.value.kind == kind


def test_benign_programs_under_the_limits_still_plan() -> None:
    program = (
        L200
        + "names = ['wood crate'] * 1\n".replace(" * 1", "")
        + "poses = [navigator.getPoseStamped(destinations[n][0:2], destinations[n][2]) for n in names]\n"
        + "navigator.startFollowWaypoints(poses)\n"
        + "navigator.info(f'{len_} zeros, going to {names}')\n".replace("{len_}", "{L[0:3]}")
        + chain(3)
        + "navigator.info(A3)\n"
    )
    plan = plan_program(program, {"wood crate": [0.0, 3.0, 0.0]})
    assert [s.method for s in plan.steps] == ["startFollowWaypoints", "info", "info"]
    assert plan.steps[1].args[0] == "[0, 0, 0] zeros, going to ['wood crate']"


def test_planning_holds_no_global_state_between_programs() -> None:
    """A refused bomb leaves nothing behind: the same thread plans a benign program right after."""
    for _ in range(3):
        with pytest.raises(ProgramRejected):
            plan_program(chain(20) + "navigator.info(A20)")
        assert plan_program("navigator.dock()").steps[0].method == "dock"


# -- the bounded formatter ---------------------------------------------------------------------------------------
def _shared(levels: int) -> list:
    value: list = [1, 2, 3, 4]
    for _ in range(levels):
        value = [value, value, value, value]
    return value


def test_formatter_work_is_bounded_by_the_limit_not_the_value() -> None:
    bomb = _shared(60)  # 4**60 leaves: repr() would never finish
    started = time.monotonic()
    text = bounded_repr(bomb, 100)
    assert time.monotonic() - started < 1.0
    assert len(text) <= 100 and text.endswith("…")
    assert text.startswith("[[[[[[[...], [...]")


def test_formatter_matches_repr_and_str_when_it_fits() -> None:
    value = [1, -2.5, "a'b", None, True, (1,), {"k": [1, 2]}]
    assert bounded_repr(value, 1000) == repr(value)
    assert bounded_text("plain text", 100) == "plain text"
    assert bounded_text(value, 1000) == str(value)
    assert format_value("x" * 10, 5, text=True) == ("xxxxx", False)


def test_formatter_never_calls_foreign_reprs_or_prints_giant_ints() -> None:
    class Evil:
        def __repr__(self) -> str:
            raise AssertionError("called")

    assert bounded_repr([Evil()], 50) == "[<Evil>]"
    assert bounded_repr(10**5000, 50) == "<int of 16610 bits>"
    assert bounded_repr(float("nan")) == "nan"


def test_formatter_is_thread_safe() -> None:
    def work() -> None:
        for _ in range(200):
            assert len(bounded_repr(_shared(30), 60)) <= 60

    assert not errors_in_threads(work, 4)
