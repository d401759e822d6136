"""Stage 2, plan: evaluate a validated program on plain data (no robot) into a checked Plan.

Our own small interpreter, never ``exec``: every value is admitted through the Budget (numbers, sizes with
sharing counted, nesting, total cells), every step ticks the work budget and the deadline (CPU time, with a
wall-clock backstop), every text a program can produce (f-strings, log messages, refusal reasons) goes through the
bounded formatter, and every goal is checked (finite, on the map, in free space). Any problem refuses the whole
program: nothing runs.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from tb4.core.directions import DIRECTIONS
from tb4.language.bounded_format import bounded_repr, format_value
from tb4.language.limits import DEFAULT_LIMITS, Limits
from tb4.language.plan_budget import Budget
from tb4.language.steps import PoseCheck, StepBuilder, is_number
from tb4.language.validate import line_of, validate
from tb4.language.vocabulary import Plan, PlanningError, Pose, ProgramRejected

__all__ = ["PoseCheck", "plan_program"]


class _Marker:
    """The value of a name that only has attributes (`navigator`, `TurtleBot4Directions`)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __bounded_format__(self) -> str:
        return self.name


_NAVIGATOR = _Marker("navigator")
_DIRECTIONS = _Marker("TurtleBot4Directions")
_COMPARE: dict[type, Callable[[Any, Any], bool]] = {
    ast.Eq: lambda a, b: a == b,
    ast.NotEq: lambda a, b: a != b,
    ast.Lt: lambda a, b: a < b,
    ast.LtE: lambda a, b: a <= b,
    ast.Gt: lambda a, b: a > b,
    ast.GtE: lambda a, b: a >= b,
}


def plan_program(
    source: str,
    destinations: Mapping[str, Sequence[float]] | None = None,
    check_pose: PoseCheck | None = None,
    limits: Limits = DEFAULT_LIMITS,
) -> Plan:
    """Validate and evaluate a program into a checked Plan, within `limits.max_plan_seconds` of this thread's CPU
    time (and `max_plan_wall_seconds` of wall time).

    Raises ProgramRejected (the program is refused) or PlanningError (the planner itself failed: out of memory,
    too deep a recursion, a bug); nothing has been executed in either case. `destinations` maps names to
    [x, y, degrees]; `check_pose(x, y)` returns a problem text or None.
    """
    try:
        budget = Budget(limits)
        tree = validate(source, limits)
        budget.check_deadline()
        return _Planner(destinations or {}, check_pose, limits, budget).run(tree)
    except (ProgramRejected, PlanningError):
        raise
    except MemoryError:
        raise PlanningError("out of memory", "the planner could not allocate memory") from None
    except RecursionError:
        raise PlanningError("recursion limit", "the planner recursed too deeply") from None
    except Exception as exc:  # noqa: BLE001 - a planner bug: say so, nothing has run
        # Only the type: str(exc) could hold a program value (a KeyError's key) and format it unbounded.
        raise PlanningError("internal error", f"{type(exc).__name__} in the planner") from None


class _Planner:
    def __init__(
        self,
        destinations: Mapping[str, Sequence[float]],
        check_pose: PoseCheck | None,
        limits: Limits,
        budget: Budget,
    ) -> None:
        self.limits = limits
        self.check_pose = check_pose
        self.budget = budget
        self.steps = StepBuilder(limits, check_pose, budget)
        self.destinations = {str(k): [float(v) for v in val] for k, val in destinations.items()}
        budget.measure(self.destinations)
        self.env: dict[str, Any] = {
            "navigator": _NAVIGATOR,
            "TurtleBot4Directions": _DIRECTIONS,
            "destinations": self.destinations,
        }

    def run(self, tree: ast.Module) -> Plan:
        for stmt in tree.body:
            self.budget.tick(line_of(stmt))
            if isinstance(stmt, ast.Assign):
                value = self.eval(stmt.value)
                for target in stmt.targets:
                    self._assign(target, value, stmt)
            elif isinstance(stmt, ast.AugAssign):
                assert isinstance(stmt.target, ast.Name)
                if stmt.target.id not in self.env:
                    raise ProgramRejected(f"name {stmt.target.id!r} is not defined", line_of(stmt))
                current = self.env[stmt.target.id]
                self.env[stmt.target.id] = self._binop(stmt.op, current, self.eval(stmt.value), stmt)
            elif isinstance(stmt, ast.Expr):
                self.eval(stmt.value)
        return self.steps.plan()

    def _admit(self, value: Any, node: ast.AST) -> Any:
        return self.budget.admit(value, line_of(node))

    def _assign(self, target: ast.expr, value: Any, node: ast.AST) -> None:
        if isinstance(target, ast.Name):
            self.env[target.id] = value
            return
        assert isinstance(target, (ast.Tuple, ast.List))
        if not isinstance(value, (list, tuple)) or len(value) != len(target.elts):
            raise ProgramRejected("cannot unpack: the number of values does not match", line_of(node))
        for t, v in zip(target.elts, value, strict=True):
            self._assign(t, v, node)

    # -- expressions -------------------------------------------------------------------------------------------
    def eval(self, node: ast.AST) -> Any:
        self.budget.tick(line_of(node))
        if isinstance(node, ast.Constant):
            return self._admit(node.value, node)
        if isinstance(node, ast.Name):
            if node.id not in self.env:
                raise ProgramRejected(f"name {node.id!r} is not defined", line_of(node))
            return self.env[node.id]
        if isinstance(node, (ast.List, ast.Tuple)):
            items = [self.eval(e) for e in node.elts]
            return self._admit(items if isinstance(node, ast.List) else tuple(items), node)
        if isinstance(node, ast.Dict):
            return self._dict(node)
        if isinstance(node, ast.UnaryOp):
            operand = self.eval(node.operand)
            if not is_number(operand):
                raise ProgramRejected("unary minus/plus only on numbers", line_of(node))
            return self._admit(-operand if isinstance(node.op, ast.USub) else +operand, node)
        if isinstance(node, ast.BinOp):
            return self._binop(node.op, self.eval(node.left), self.eval(node.right), node)
        if isinstance(node, ast.Compare):
            return self._compare(node)
        if isinstance(node, ast.Subscript):
            return self._subscript(node)
        if isinstance(node, ast.Attribute):
            if self.eval(node.value) is _DIRECTIONS:
                return DIRECTIONS[node.attr]
            raise ProgramRejected(f"{ast.unparse(node)[:60]} can only be called", line_of(node))
        if isinstance(node, ast.Call):
            return self._call(node)
        if isinstance(node, ast.ListComp):
            return self._listcomp(node)
        if isinstance(node, ast.JoinedStr):
            return self._fstring(node)
        raise ProgramRejected(f"{type(node).__name__} is not allowed", line_of(node))

    def _dict(self, node: ast.Dict) -> dict[Any, Any]:
        if len(node.keys) > self.limits.max_list:
            raise ProgramRejected("dictionary too large", line_of(node))
        out: dict[Any, Any] = {}
        for k, v in zip(node.keys, node.values, strict=True):
            if k is None:
                raise ProgramRejected("** in dictionaries is not allowed", line_of(node))
            key = self.eval(k)
            if not isinstance(key, (str, int, float, bool)):
                raise ProgramRejected("dictionary keys must be numbers or strings", line_of(node))
            out[key] = self.eval(v)
        return self._admit(out, node)

    def _fstring(self, node: ast.JoinedStr) -> str:
        parts: list[str] = []
        room = self.limits.max_string
        for value in node.values:
            if isinstance(value, ast.Constant):
                text = str(value.value)
            else:
                assert isinstance(value, ast.FormattedValue)
                text, complete = format_value(self.eval(value.value), room + 1, text=True)
                if not complete:
                    text += "?"  # more than fits: the length check below refuses it
            parts.append(text)
            room -= len(text)
            if room < 0:
                raise ProgramRejected(f"string too long (limit {self.limits.max_string})", line_of(node))
        return self._admit("".join(parts), node)

    def _binop(self, op: ast.operator, left: Any, right: Any, node: ast.AST) -> Any:
        if is_number(left) and is_number(right):
            if isinstance(op, ast.Add):
                result = left + right
            elif isinstance(op, ast.Sub):
                result = left - right
            elif isinstance(op, ast.Mult):
                result = left * right
            elif isinstance(op, ast.Div):
                if right == 0:
                    raise ProgramRejected("division by zero", line_of(node))
                result = left / right
            else:
                raise ProgramRejected(f"operator {type(op).__name__} is not allowed", line_of(node))
            return self._admit(result, node)
        if isinstance(op, ast.Add) and isinstance(left, str) and isinstance(right, str):
            if len(left) + len(right) > self.limits.max_string:  # check before building it
                raise ProgramRejected(f"string too long (limit {self.limits.max_string})", line_of(node))
            return self._admit(left + right, node)
        if isinstance(op, ast.Add) and isinstance(left, list) and isinstance(right, list):
            if len(left) + len(right) > self.limits.max_list:
                raise ProgramRejected(f"list too long (limit {self.limits.max_list})", line_of(node))
            return self._admit(left + right, node)
        raise ProgramRejected(
            f"operator {type(op).__name__} not allowed between {_kind(left)} and {_kind(right)}", line_of(node)
        )

    def _compare(self, node: ast.Compare) -> bool:
        left = self.eval(node.left)
        for op, comparator in zip(node.ops, node.comparators, strict=True):
            right = self.eval(comparator)
            if not (_is_plain(left) and _is_plain(right)):
                raise ProgramRejected("comparisons only between numbers or strings", line_of(node))
            try:
                ok = _COMPARE[type(op)](left, right)
            except TypeError:
                raise ProgramRejected("cannot compare these values", line_of(node)) from None
            if not ok:
                return False
            left = right
        return True

    def _subscript(self, node: ast.Subscript) -> Any:
        base = self.eval(node.value)
        if isinstance(node.slice, ast.Slice):
            if not isinstance(base, (list, tuple, str)):
                raise ProgramRejected(f"cannot slice a {_kind(base)}", line_of(node))
            bounds = []
            for part in (node.slice.lower, node.slice.upper, node.slice.step):
                value = None if part is None else self.eval(part)
                if value is not None and (not isinstance(value, int) or isinstance(value, bool)):
                    raise ProgramRejected("slice bounds must be integers", line_of(node))
                bounds.append(value)
            if bounds[2] == 0:
                raise ProgramRejected("slice step cannot be zero", line_of(node))
            return self._admit(base[slice(*bounds)], node)
        key = self.eval(node.slice)
        if isinstance(base, dict):
            if not isinstance(key, (str, int, float, bool)) or key not in base:
                if base is self.destinations:
                    known = bounded_repr(list(base), 160)
                    raise ProgramRejected(
                        f"unknown destination {bounded_repr(key, 60)} (known: {known})", line_of(node)
                    )
                raise ProgramRejected(f"key {bounded_repr(key, 60)} not found", line_of(node))
            value = base[key]
            return self._admit(list(value), node) if isinstance(value, list) else value
        if isinstance(base, (list, tuple, str)):
            if not isinstance(key, int) or isinstance(key, bool):
                raise ProgramRejected("list indices must be integers", line_of(node))
            if not -len(base) <= key < len(base):
                raise ProgramRejected(f"index {key} out of range", line_of(node))
            return base[key]
        raise ProgramRejected(f"cannot index a {_kind(base)}", line_of(node))

    def _listcomp(self, node: ast.ListComp) -> list[Any]:
        gen = node.generators[0]
        iterable = self.eval(gen.iter)
        if isinstance(iterable, dict):
            iterable = self._admit(list(iterable), node)
        if not isinstance(iterable, (list, tuple)):
            raise ProgramRejected(f"can only iterate over a list, not a {_kind(iterable)}", line_of(node))
        saved = dict(self.env)
        out: list[Any] = []
        cells = 1
        try:
            for item in iterable:
                self._assign(gen.target, item, node)
                if all(self.eval(cond) for cond in gen.ifs):
                    element = self.eval(node.elt)
                    cells += self.budget.measure(element)[0]
                    if len(out) >= self.limits.max_list or cells > self.limits.max_value_cells:
                        raise ProgramRejected("list comprehension builds too large a list", line_of(node))
                    out.append(element)
        finally:
            self.env = saved
        return self._admit(out, node)

    def _call(self, node: ast.Call) -> Any:
        func = node.func
        method = func.attr if isinstance(func, ast.Attribute) else "getPoseStamped"
        args = [self.eval(a) for a in node.args]
        kwargs = [(kw.arg, self.eval(kw.value)) for kw in node.keywords if kw.arg is not None]
        return self.steps.call(method, args, kwargs, line_of(node))


def _is_plain(value: Any) -> bool:
    return isinstance(value, (int, float, str, bool)) or value is None


def _kind(value: Any) -> str:
    if isinstance(value, Pose):
        return "pose"
    if isinstance(value, _Marker):
        return value.name
    return type(value).__name__
