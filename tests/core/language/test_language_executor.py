"""The safe executor: good programs plan and run; hostile programs are refused whole, with nothing executed."""

from __future__ import annotations

import math
import time

import pytest
from threads import errors_in_threads

from tb4.language.executor import (
    ALLOWED_METHODS,
    Limits,
    Pose,
    ProgramRejected,
    plan_program,
    run_program,
    validate,
)

WOOD = "navigator.getPoseStamped(destinations['wood crate'][0:2], destinations['wood crate'][2])"
LIST50 = "L = [" + ", ".join(str(i) for i in range(50)) + "]\n"
LIST10 = "L = [" + ", ".join(str(i) for i in range(10)) + "]\n"

# (id, program): every one must be refused before anything runs.
HOSTILE: list[tuple[str, str]] = [
    ("import", "import os\nos.system('touch /tmp/pwned')"),
    ("from-import", "from os import system\nsystem('id')"),
    ("dunder-import", "__import__('os').system('id')"),
    ("import-inside-expr", "navigator.info(__import__('os').getcwd())"),
    ("dunder-walk-to-subclasses", "x = ().__class__.__bases__[0].__subclasses__()"),
    ("dunder-walk-to-globals", "g = navigator.__class__.__init__.__globals__['os']"),
    ("dunder-dict", "d = navigator.__dict__"),
    ("method-globals", "g = navigator.getPoseStamped.__globals__"),
    ("directions-class", "c = TurtleBot4Directions.__class__"),
    ("bound-self", "s = navigator.info.__self__"),
    ("private-attribute", "navigator._task_client.cancel()"),
    ("private-name", "_x = 1"),
    ("eval", "eval('1+1')"),
    ("exec", "exec('import os')"),
    ("compile", "compile('1', 'f', 'eval')"),
    ("open", "open('/etc/passwd').read()"),
    ("getattr", "getattr(navigator, 'destroyNode')()"),
    ("globals", "globals()['navigator']"),
    ("print", "print('hello')"),
    ("destroyNode", "navigator.destroyNode()"),
    ("lifecycleShutdown", "navigator.lifecycleShutdown()"),
    ("alias-then-call", "x = navigator.dock\nx()"),
    ("call-through-dunder-call", "navigator.cancelTask.__call__()"),
    ("str-format-attribute", "navigator.info('{0.__class__}'.format(navigator))"),
    ("fstring-conversion", "navigator.info(f'{navigator!r}')"),
    ("while-true", "while True:\n    navigator.spin()"),
    ("for-range", "for i in range(10**9):\n    navigator.spin()"),
    ("huge-range-comprehension", "x = [0 for i in range(10**12)]"),
    ("nested-comprehensions", LIST10 + "x = [[[[[a for a in L] for b in L] for c in L] for d in L] for e in L]"),
    ("generator-expression", "x = list(i for i in [1, 2])"),
    ("list-repetition", "x = [1] * 1000000000"),
    ("power", "x = 10 ** 10 ** 10"),
    ("string-repetition", "navigator.info('a' * 1000000)"),
    ("nan-via-float", "navigator.startToPose(navigator.getPoseStamped([float('nan'), 0.0], 0))"),
    ("inf-literal", "navigator.startToPose(navigator.getPoseStamped([1e999, 0.0], 0))"),
    ("inf-by-overflow", "x = 1e300 * 1e300\nnavigator.startToPose(navigator.getPoseStamped([x, 0.0], 0))"),
    ("nan-heading", "navigator.startToPose(navigator.getPoseStamped([1.0, 1.0], 1e999 - 1e999))"),
    ("off-the-map", "navigator.startToPose(navigator.getPoseStamped([100.0, 100.0], 0))"),
    ("inside-an-obstacle", "navigator.startToPose(navigator.getPoseStamped([7.5, 3.6], 0))"),
    ("huge-coordinate", "navigator.startToPose(navigator.getPoseStamped([1e7, 0.0], 0))"),
    (
        "thousands-of-goals",
        LIST50 + "M = L + L + L + L\n"
        "navigator.startFollowWaypoints([navigator.getPoseStamped([1.0, 1.0], 0) for i in M])",
    ),
    ("thousands-of-statements", ("navigator.startToPose(" + WOOD + ")\n") * 1000),
    ("many-statements-semicolons", "navigator.dock(); " * 60),
    ("many-goal-calls", ("navigator.startToPose(" + WOOD + ")\n") * 25),
    ("function-definition", "def f():\n    navigator.dock()\nf()"),
    ("async-function", "async def f():\n    pass"),
    ("class-definition", "class A:\n    pass"),
    ("lambda", "f = lambda: navigator.dock()"),
    ("with", "with open('x') as f:\n    pass"),
    ("try", "try:\n    navigator.dock()\nexcept Exception:\n    pass"),
    ("raise", "raise SystemExit(1)"),
    ("if", "if True:\n    navigator.dock()"),
    ("ternary", "x = 1 if True else 2"),
    ("walrus", "(x := navigator.dock())"),
    ("del", "del navigator"),
    ("global", "global navigator"),
    ("assert", "assert False"),
    ("attribute-assignment", "navigator.dock = None"),
    ("item-assignment", "destinations['wood crate'] = [100, 100, 0]"),
    ("rebind-navigator", "navigator = None"),
    ("rebind-destinations", "destinations = {}"),
    ("starred-args", "navigator.startToPose(*[1])"),
    ("kwargs-expansion", "navigator.info(**{'msg': 'x'})"),
    ("spin-out-of-bounds", "navigator.spin(1e5)"),
    ("backup-negative", "navigator.backup(backup_dist=-5.0)"),
    ("backup-too-fast", "navigator.backup(0.5, 5.0)"),
    ("unknown-keyword", "navigator.spin(spin_dist=1.0, callback=print)"),
    ("pose-not-from-getPoseStamped", "navigator.startToPose(destinations['wood crate'])"),
    ("strings-as-coordinates", "navigator.startToPose(navigator.getPoseStamped(['a', 'b'], 0))"),
    ("unknown-destination", "navigator.startToPose(navigator.getPoseStamped(destinations['vault'][0:2], 0))"),
    ("bytes-constant", "x = b'\\x00'"),
    ("deep-nesting", "x = " + "-" * 400 + "1"),
    ("deep-lists", "x = " + "[" * 200 + "]" * 200),
    ("nul-byte", "navigator.dock()\x00"),
    ("syntax-error", "navigator.dock("),
    ("in-operator-dunder-probe", "x = '__class__' in navigator"),
    ("set-literal", "x = {1, 2}"),
    ("boolean-op-shortcut", "x = navigator.dock() or navigator.undock()"),
    ("too-long", "navigator.info('" + "a" * 5000 + "')"),
]


@pytest.mark.parametrize("program", [p for _, p in HOSTILE], ids=[i for i, _ in HOSTILE])
def test_hostile_program_is_refused_and_nothing_runs(program, depot_context, recorder) -> None:
    table, check = depot_context
    started = time.monotonic()
    with pytest.raises(ProgramRejected) as info:
        run_program(program, recorder, table, check)
    assert time.monotonic() - started < 5.0, "refusing must be quick (no work before the refusal)"
    assert info.value.reason
    assert recorder.calls == [], f"something ran: {recorder.calls}"


def test_the_hostile_suite_is_large_and_named_uniquely() -> None:
    ids = [i for i, _ in HOSTILE]
    assert len(ids) >= 30
    assert len(set(ids)) == len(ids)


@pytest.mark.parametrize(
    "program",
    [
        "navigator.dock()\nimport os",
        "navigator.dock()\nnavigator.startToPose(navigator.getPoseStamped([float('inf'), 0.0], 0))",
        "navigator.undock()\nnavigator.startToPose(navigator.getPoseStamped([100.0, 0.0], 0))",
        "navigator.info('moving')\nnavigator.startToPose(" + WOOD + ")\nnavigator.destroyNode()",
        "navigator.dock()\nx = destinations['nowhere']",
    ],
)
def test_a_program_refused_late_is_never_partly_executed(program, depot_context, recorder) -> None:
    table, check = depot_context
    with pytest.raises(ProgramRejected):
        run_program(program, recorder, table, check)
    assert recorder.calls == []


def test_refusal_names_the_line_and_the_reason() -> None:
    with pytest.raises(ProgramRejected) as info:
        validate("navigator.dock()\nimport os\n")
    assert info.value.line == 2
    assert "import" in info.value.reason
    with pytest.raises(ProgramRejected, match="destroyNode"):
        validate("navigator.destroyNode()")


def test_upstream_style_programs_plan_and_run(depot_context, recorder) -> None:
    table, check = depot_context
    program = (
        "# go to the crate, then through two poses, then dock\n"
        f"goal = {WOOD}\n"
        "navigator.startToPose(goal)\n"
        "poses = [navigator.getPoseStamped([-1.0, 0.0], TurtleBot4Directions.EAST),\n"
        "         navigator.getPoseStamped([2.0, 1.0], 90)]\n"
        "navigator.startThroughPoses(poses)\n"
        "names = ['steel barrels', 'bathroom door']\n"
        "navigator.startFollowWaypoints([navigator.getPoseStamped(destinations[n][0:2], destinations[n][2])"
        " for n in names])\n"
        "navigator.info(f'visited {len_names} places')\n".replace("{len_names}", "{names}")
        + "navigator.spin(spin_dist=1.57)\n"
        "navigator.backup(0.2, 0.1)\n"
        "navigator.dock()\n"
    )
    plan, report = run_program(program, recorder, table, check)
    assert report.ok and report.completed == len(plan.steps) == 7
    assert plan.goals == 5
    names = [c[0] for c in recorder.calls]
    assert names == ["goToPose", "goThroughPoses", "followWaypoints", "info", "spin", "backup", "dock"]
    assert recorder.calls[0][1] == ((0.0, 3.0, 0.0),)
    assert recorder.calls[1][1] == ([(-1.0, 0.0, 270.0), (2.0, 1.0, 90.0)],)
    assert recorder.calls[2][1] == ([(2.0, 2.0, 90.0), (-6.0, -6.0, 180.0)],)
    assert "steel barrels" in recorder.calls[3][1][0]
    assert recorder.calls[4][1] == (1.57, 10)


def test_plain_arithmetic_and_unpacking(depot_context, recorder) -> None:
    table, check = depot_context
    program = "x, y = 1.5, -2\nx += 0.5\nnavigator.startToPose(navigator.getPoseStamped([x, y / 2], 45 + 90))\n"
    plan = plan_program(program, table, check)
    assert plan.steps[0].args[0] == Pose(2.0, -1.0, 135.0)


def test_every_allowed_method_exists_on_the_real_navigator_api() -> None:
    expected = {
        "dock",
        "undock",
        "getPoseStamped",
        "startToPose",
        "startThroughPoses",
        "startFollowWaypoints",
        "info",
        "warn",
        "error",
        "debug",
        "cancelTask",
        "spin",
        "backup",
        "driveOnHeading",
    }
    assert set(ALLOWED_METHODS) == expected
    for name in ("destroyNode", "lifecycleShutdown", "setInitialPose", "changeMap", "createPath"):
        assert name not in ALLOWED_METHODS


def test_goal_and_step_limits_are_configurable(depot_context) -> None:
    table, check = depot_context
    program = f"navigator.startToPose({WOOD})\n" * 3
    assert plan_program(program, table, check).goals == 3
    with pytest.raises(ProgramRejected, match="too many goals"):
        plan_program(program, table, check, Limits(max_goals=2))


def test_values_are_bounded_while_planning() -> None:
    with pytest.raises(ProgramRejected, match="too large"):
        plan_program("x = 1000.0 * 1000.0 * 1000.0")
    with pytest.raises(ProgramRejected, match="list too long"):
        plan_program(LIST50 + "M = L + L + L + L + L")
    assert math.isfinite(plan_program("x = 3.0 / 4").goals)


def test_planning_is_thread_safe_and_independent(depot_context) -> None:
    table, check = depot_context

    def work() -> None:
        for _ in range(20):
            plan_program(f"navigator.startToPose({WOOD})", table, check)

    assert not errors_in_threads(work, 4)
    assert table["wood crate"] == [0.0, 3.0, 0.0], "programs must not change the shared destination table"


def test_validating_and_planning_import_no_ros() -> None:
    import subprocess
    import sys

    code = (
        "import sys; from tb4.language.executor import plan_program; import tb4.language.commands;"
        "plan_program('navigator.dock()');"
        "bad = [m for m in sys.modules if m.split('.')[0] in ('rclpy', 'action_msgs')]; print(bad); sys.exit(bool(bad))"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.parametrize("bad", [-1, float("nan"), float("inf"), "10", True])
def test_limits_must_be_finite_non_negative_numbers(bad) -> None:
    with pytest.raises(ValueError, match="Limits.max_plan_seconds"):
        Limits(max_plan_seconds=bad)
