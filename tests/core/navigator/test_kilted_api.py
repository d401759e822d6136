"""Our public API against Nav2 Kilted's, name by name and parameter by parameter, so drift fails CI.

The reference (data/kilted-simple-commander-api.md, a copy of the shared reference: facts, no upstream code) lists
every public class, method, parameter, default and annotation of Kilted's robot_navigator.py and utils.py. Rules:
- every class, enum member (same value), method and function exists, under both import paths;
- upstream's parameters come first, in order, same names, same kinds, same defaults; extra ones have defaults;
- a parameter annotation may only widen upstream's (accept more); a return annotation must match, except the
  deliberate, documented differences in the tables below.
"""

from __future__ import annotations

import ast
import enum
import inspect
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("nav2_msgs.action", reason="interface packages not built")

REFERENCE = Path(__file__).parent / "data" / "kilted-simple-commander-api.md"

#: (method, parameter): (upstream, ours, why) for parameter annotations that are not a plain widening.
PARAM_DIFFERENCES = {
    ("spin", "time_allowance"): ("int", "float", "any positive seconds; an int is still accepted"),
    ("backup", "time_allowance"): ("int", "float", "same"),
    ("driveOnHeading", "time_allowance"): ("int", "float", "same"),
    ("assistedTeleop", "time_allowance"): ("int", "float", "same"),
}
#: method: (upstream, ours, why) for return annotations that differ.
RETURN_DIFFERENCES = {
    "getPath": ("Path", "Path | None", "upstream returns None on failure despite its annotation"),
    "getPathThroughPoses": ("Path", "Path | None", "same"),
    "smoothPath": ("Path", "Path | None", "same"),
    "getGlobalCostmap": ("OccupancyGrid", "Costmap", "upstream returns GetCostmap's nav2_msgs/Costmap too"),
    "getLocalCostmap": ("OccupancyGrid", "Costmap", "same"),
    "lifecycleStartup": ("None", "bool", "True when every manager succeeded; callers ignoring it are unaffected"),
    "lifecycleShutdown": ("None", "bool", "same"),
}


def _reference() -> ast.Module:
    text = REFERENCE.read_text()
    start = text.index("```python") + len("```python")
    return ast.parse(text[start : text.index("```", start)])


def _members(node: ast.expr) -> frozenset[str]:
    """An annotation as a set of normalised union members: Optional[X] == X | None, Union[A, B] == A | B."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitOr):
        return _members(node.left) | _members(node.right)
    if isinstance(node, ast.Constant) and node.value is None:
        return frozenset({"None"})
    if isinstance(node, ast.Subscript):
        head = ast.unparse(node.value)
        args = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
        if head == "Optional":
            return _members(args[0]) | {"None"}
        if head == "Union":
            return frozenset().union(*(_members(a) for a in args))
        inner = ", ".join(" | ".join(sorted(_members(a))) for a in args)
        return frozenset({f"{head}[{inner}]"})
    return frozenset({ast.unparse(node)})


def _norm(annotation: Any) -> frozenset[str]:
    if annotation is inspect.Parameter.empty:
        return frozenset()
    text = annotation if isinstance(annotation, str) else inspect.formatannotation(annotation)
    return _members(ast.parse(text, mode="eval").body)


def _literal(node: ast.expr | None, namespace: dict[str, Any]) -> Any:
    if node is None:
        return inspect.Parameter.empty
    return eval(compile(ast.Expression(node), "<reference>", "eval"), namespace)  # noqa: S307 - our own data file


def _classes() -> dict[str, ast.ClassDef]:
    return {n.name: n for n in _reference().body if isinstance(n, ast.ClassDef)}


def _functions() -> list[ast.FunctionDef]:
    return [n for n in _reference().body if isinstance(n, ast.FunctionDef)]


def _methods() -> list[ast.FunctionDef]:
    return [n for n in _classes()["BasicNavigator"].body if isinstance(n, ast.FunctionDef)]


def test_the_reference_is_what_we_think_it_is() -> None:
    # A truncated or reformatted reference would make every check below pass vacuously.
    assert set(_classes()) == {"TaskResult", "RunningTask", "BasicNavigator"}
    assert len(_methods()) == 43 and len(_functions()) == 4


@pytest.mark.parametrize("name", ["TaskResult", "RunningTask"])
def test_enums_have_upstreams_members_and_values(name: str) -> None:
    import nav2_simple_commander.robot_navigator as upstream_path
    import tb4.navigator as ours

    expected = {}
    for stmt in _classes()[name].body:
        assert isinstance(stmt, ast.Assign)
        expected[stmt.targets[0].id] = ast.literal_eval(stmt.value)  # type: ignore[attr-defined]
    cls = getattr(ours, name)
    assert issubclass(cls, enum.Enum) and getattr(upstream_path, name) is cls
    assert {m.name: m.value for m in cls} == expected


def _check_signature(ours: Any, ref: ast.FunctionDef, namespace: dict[str, Any], where: str) -> list[str]:
    problems: list[str] = []
    name = ref.name
    params = list(inspect.signature(ours).parameters.values())
    ref_args = ref.args.args
    defaults: list[ast.expr | None] = [None] * (len(ref_args) - len(ref.args.defaults)) + list(ref.args.defaults)
    if ref_args and ref_args[0].arg == "self":
        ref_args, defaults = ref_args[1:], defaults[1:]
        params = params[1:] if params and params[0].name == "self" else params
    if len(params) < len(ref_args):
        return [f"{where}{name}: {len(params)} parameters, upstream has {len(ref_args)}"]
    for ref_arg, ref_default, ours_param in zip(ref_args, defaults, params, strict=False):
        p = f"{where}{name}({ref_arg.arg})"
        if ours_param.name != ref_arg.arg:
            problems.append(f"{p}: ours is named '{ours_param.name}'")
            continue
        if ours_param.kind is not inspect.Parameter.POSITIONAL_OR_KEYWORD:
            problems.append(f"{p}: must be positional-or-keyword, is {ours_param.kind.name}")
        expected = _literal(ref_default, namespace)
        if ours_param.default != expected or type(ours_param.default) is not type(expected):
            problems.append(f"{p}: default {ours_param.default!r}, upstream {expected!r}")
        if ref_arg.annotation is not None:
            theirs, mine = _members(ref_arg.annotation), _norm(ours_param.annotation)
            allowed = PARAM_DIFFERENCES.get((name, ref_arg.arg))
            if allowed is not None:
                if (theirs, mine) != (_norm(allowed[0]), _norm(allowed[1])):
                    problems.append(f"{p}: annotation {sorted(mine)} vs upstream {sorted(theirs)} (table is stale)")
            elif not theirs <= mine:
                problems.append(f"{p}: annotation {sorted(mine)} does not accept upstream's {sorted(theirs)}")
    for extra in params[len(ref_args) :]:
        if extra.default is inspect.Parameter.empty and extra.kind not in (
            inspect.Parameter.VAR_POSITIONAL,
            inspect.Parameter.VAR_KEYWORD,
        ):
            problems.append(f"{where}{name}: extra parameter '{extra.name}' has no default (breaks upstream calls)")
    if ref.returns is not None:
        theirs = _members(ref.returns)
        mine = _norm(inspect.signature(ours).return_annotation)
        allowed_return = RETURN_DIFFERENCES.get(name)
        if allowed_return is not None:
            if (theirs, mine) != (_norm(allowed_return[0]), _norm(allowed_return[1])):
                problems.append(f"{where}{name}: returns {sorted(mine)} vs upstream {sorted(theirs)} (table is stale)")
        elif theirs != mine:
            problems.append(f"{where}{name}: returns {sorted(mine)}, upstream {sorted(theirs)}")
    return problems


def test_basic_navigator_matches_kilted_method_by_method() -> None:
    from nav2_simple_commander.robot_navigator import BasicNavigator as UpstreamPath
    from tb4.navigator import BasicNavigator, RunningTask, TurtleBot4Navigator

    assert UpstreamPath is BasicNavigator
    namespace = {"RunningTask": RunningTask}
    problems: list[str] = []
    for ref in _methods():
        for cls in (BasicNavigator, TurtleBot4Navigator):
            method = getattr(cls, ref.name, None)
            if not callable(method):
                problems.append(f"{cls.__name__}.{ref.name}: missing")
                continue
            if ref.name == "__init__" and cls is TurtleBot4Navigator:
                continue  # turtlebot4_navigation's own constructor: TurtleBot4Navigator(namespace='')
            problems += _check_signature(method, ref, namespace, f"{cls.__name__}.")
    assert problems == []


def test_the_deviation_tables_name_real_methods() -> None:
    names = {m.name for m in _methods()}
    assert {m for m, _ in PARAM_DIFFERENCES} <= names and set(RETURN_DIFFERENCES) <= names


def test_utils_functions_match() -> None:
    import nav2_simple_commander.utils as upstream_path
    import tb4.navigator.utils as ours

    problems: list[str] = []
    for ref in _functions():
        function = getattr(ours, ref.name, None)
        assert getattr(upstream_path, ref.name, None) is function, ref.name
        problems += _check_signature(function, ref, {}, "utils.")
    assert problems == []


def test_a_drifted_signature_is_caught() -> None:
    """The checker itself can fail: a renamed parameter, a changed default and a narrowed return are reported."""

    def spin(self, spin_distance: float = 1.0, time_allowance: str = "10", collisions: bool = False) -> bool:  # type: ignore[no-untyped-def]
        return True

    ref = next(m for m in _methods() if m.name == "spin")
    problems = _check_signature(spin, ref, {}, "")
    assert any("named 'spin_distance'" in p for p in problems)
    assert any("returns" in p for p in problems)
    assert any("time_allowance): default '10'" in p for p in problems)
    assert any("named 'collisions'" in p for p in problems)
    assert any("time_allowance): annotation" in p for p in problems)

    def backup(self, backup_dist: float = 0.15) -> None:  # type: ignore[no-untyped-def]
        return None

    ref = next(m for m in _methods() if m.name == "backup")
    assert _check_signature(backup, ref, {}, "") == ["backup: 1 parameters, upstream has 4"]
