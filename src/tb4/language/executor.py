"""Safe executor for robot programs written by a language model (or by the offline interpreter).

Upstream hands the model's text to ``exec()``: whoever can publish on ``user_input`` (or a confused model) runs
arbitrary Python on the robot. Here a program is never given to ``exec``/``eval``. It goes through three stages:

1. ``validate``: parse with ``ast`` and accept only straight-line code built from assignments, literals, arithmetic,
   destination look-ups, ``TurtleBot4Directions`` members, bounded list comprehensions and calls to an explicit
   allow-list of navigator methods. Everything else (imports, dunder or private names, any other call, loops,
   definitions, ...) is refused with the line and the reason.
2. ``plan``: our own small interpreter evaluates the validated tree against pure data (no robot), producing a
   list of ``Step``s. Every value is bounded (numbers, string and list sizes, evaluation steps), every pose is
   checked (finite, on the map, in free space) and the goal count is capped. Any failure refuses the whole program.
3. ``execute``: the plan is replayed on the navigator, one allowed method at a time, under a wall-clock budget
   (a watchdog cancels the running task when the budget is spent).

So a refused program is never partly executed: nothing touches the robot before the whole plan is known and valid.
"""

from __future__ import annotations

import ast
import contextlib
import math
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "DIRECTIONS",
    "ALLOWED_METHODS",
    "ProgramRejected",
    "Limits",
    "DEFAULT_LIMITS",
    "Pose",
    "Step",
    "Plan",
    "ExecutionReport",
    "validate",
    "plan_program",
    "execute_plan",
    "run_program",
]

#: TurtleBot4Directions members (degrees, map-relative: NORTH = +x, WEST = +y).
DIRECTIONS: dict[str, int] = {
    "NORTH": 0,
    "NORTH_WEST": 45,
    "WEST": 90,
    "SOUTH_WEST": 135,
    "SOUTH": 180,
    "SOUTH_EAST": 225,
    "EAST": 270,
    "NORTH_EAST": 315,
}


@dataclass(frozen=True)
class _MethodSpec:
    """Parameters a navigator method accepts (name, default or _REQUIRED), and numeric bounds per parameter."""

    params: tuple[tuple[str, Any], ...]
    bounds: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    goals: bool = False  # counts towards the goal limit


_REQUIRED = object()

#: The navigator methods a program may call. Nothing else is reachable from a program.
ALLOWED_METHODS: dict[str, _MethodSpec] = {
    "dock": _MethodSpec(()),
    "undock": _MethodSpec(()),
    "getPoseStamped": _MethodSpec((("position", _REQUIRED), ("rotation", 0))),
    "startToPose": _MethodSpec((("pose", _REQUIRED),), goals=True),
    "startThroughPoses": _MethodSpec((("poses", _REQUIRED),), goals=True),
    "startFollowWaypoints": _MethodSpec((("poses", _REQUIRED),), goals=True),
    "info": _MethodSpec((("msg", _REQUIRED),)),
    "warn": _MethodSpec((("msg", _REQUIRED),)),
    "error": _MethodSpec((("msg", _REQUIRED),)),
    "debug": _MethodSpec((("msg", _REQUIRED),)),
    "cancelTask": _MethodSpec(()),
    "spin": _MethodSpec(
        (("spin_dist", 1.57), ("time_allowance", 10)),
        {"spin_dist": (-4 * math.pi, 4 * math.pi), "time_allowance": (1, 120)},
    ),
    "backup": _MethodSpec(
        (("backup_dist", 0.15), ("backup_speed", 0.025), ("time_allowance", 10)),
        {"backup_dist": (0.0, 2.0), "backup_speed": (0.0, 0.31), "time_allowance": (1, 120)},
    ),
    "driveOnHeading": _MethodSpec(
        (("dist", 0.15), ("speed", 0.025), ("time_allowance", 10)),
        {"dist": (0.0, 3.0), "speed": (0.0, 0.31), "time_allowance": (1, 120)},
    ),
}

_TASK_METHODS = ("spin", "backup", "driveOnHeading")  # non-blocking upstream: the executor waits for them
_RESERVED = ("navigator", "TurtleBot4Directions", "destinations")


class ProgramRejected(Exception):
    """The program was refused (nothing was executed); `reason` says why, `line` where (0 when not known)."""

    def __init__(self, reason: str, line: int = 0) -> None:
        self.reason = reason
        self.line = line
        super().__init__(f"line {line}: {reason}" if line else reason)


@dataclass(frozen=True)
class Limits:
    """Bounds on a program: source size, statements, goals, values, evaluation work and run time."""

    max_chars: int = 4000
    max_nodes: int = 1500
    max_depth: int = 30
    max_statements: int = 40
    max_goals: int = 20
    max_steps: int = 60
    max_list: int = 200
    max_string: int = 500
    max_abs_number: float = 1e6
    max_eval_ops: int = 20000
    max_run_seconds: float = 900.0
    task_wait_seconds: float = 150.0


DEFAULT_LIMITS = Limits()


@dataclass(frozen=True)
class Pose:
    """A pose a program asked for: map frame, metres, heading in degrees (TurtleBot4Directions convention)."""

    x: float
    y: float
    degrees: float


@dataclass(frozen=True)
class Step:
    """One navigator call of a plan, with its arguments already evaluated and checked."""

    method: str
    args: tuple[Any, ...] = ()
    line: int = 0

    def describe(self) -> str:
        def fmt(a: Any) -> str:
            if isinstance(a, Pose):
                return f"({a.x:g}, {a.y:g}, {a.degrees:g}°)"
            if isinstance(a, list):
                return "[" + ", ".join(fmt(p) for p in a) + "]"
            return repr(a)

        return f"{self.method}(" + ", ".join(fmt(a) for a in self.args) + ")"


@dataclass(frozen=True)
class Plan:
    """The checked list of navigator calls a program makes, and how many goal poses it sends."""

    steps: tuple[Step, ...]
    goals: int

    def describe(self) -> str:
        return "; ".join(s.describe() for s in self.steps) or "(no robot actions)"


@dataclass
class ExecutionReport:
    """What happened when a plan ran: steps completed, and why it stopped early (empty if it did not)."""

    completed: int = 0
    total: int = 0
    stopped: str = ""

    @property
    def ok(self) -> bool:
        return not self.stopped and self.completed == self.total


# --------------------------------------------------------------------------------------------------------------
# Stage 1: static validation
# --------------------------------------------------------------------------------------------------------------

_STATEMENTS = (ast.Assign, ast.AugAssign, ast.Expr, ast.Pass)
_EXPRESSIONS = (
    ast.Constant,
    ast.Name,
    ast.List,
    ast.Tuple,
    ast.Dict,
    ast.UnaryOp,
    ast.BinOp,
    ast.Subscript,
    ast.Slice,
    ast.Attribute,
    ast.Call,
    ast.ListComp,
    ast.comprehension,
    ast.JoinedStr,
    ast.FormattedValue,
    ast.keyword,
    ast.Compare,
)
_CONTEXTS = (ast.Load, ast.Store)
_OPERATORS = (
    ast.Add,
    ast.Sub,
    ast.Mult,
    ast.Div,
    ast.USub,
    ast.UAdd,
    ast.Eq,
    ast.NotEq,
    ast.Lt,
    ast.LtE,
    ast.Gt,
    ast.GtE,
)
_FORBIDDEN_WHY: dict[type, str] = {
    ast.Import: "imports are not allowed",
    ast.ImportFrom: "imports are not allowed",
    ast.FunctionDef: "function definitions are not allowed",
    ast.AsyncFunctionDef: "function definitions are not allowed",
    ast.ClassDef: "class definitions are not allowed",
    ast.Lambda: "lambdas are not allowed",
    ast.While: "while loops are not allowed (programs are straight-line code)",
    ast.For: "for loops are not allowed (programs are straight-line code; use a list of poses)",
    ast.AsyncFor: "loops are not allowed",
    ast.If: "if statements are not allowed (programs are straight-line code)",
    ast.IfExp: "conditional expressions are not allowed",
    ast.With: "with statements are not allowed",
    ast.Try: "try statements are not allowed",
    ast.Raise: "raise is not allowed",
    ast.Global: "global is not allowed",
    ast.Nonlocal: "nonlocal is not allowed",
    ast.Delete: "del is not allowed",
    ast.Return: "return is not allowed",
    ast.Yield: "generators are not allowed",
    ast.YieldFrom: "generators are not allowed",
    ast.Await: "await is not allowed",
    ast.GeneratorExp: "generator expressions are not allowed",
    ast.SetComp: "set comprehensions are not allowed",
    ast.DictComp: "dict comprehensions are not allowed",
    ast.NamedExpr: "the walrus operator is not allowed",
    ast.Starred: "star arguments are not allowed",
    ast.Assert: "assert is not allowed",
    ast.Set: "sets are not allowed",
    ast.BoolOp: "boolean operators are not allowed",
}


def _line(node: ast.AST) -> int:
    return int(getattr(node, "lineno", 0) or 0)


def _check_name(name: str, node: ast.AST) -> None:
    if name.startswith("_"):
        raise ProgramRejected(f"private or dunder name {name!r} is not allowed", _line(node))


def validate(source: str, limits: Limits = Limits()) -> ast.Module:
    """Parse and statically check a program; raise ProgramRejected with the first problem found."""
    if not isinstance(source, str):
        raise ProgramRejected("a program must be text")
    if len(source) > limits.max_chars:
        raise ProgramRejected(f"program too long ({len(source)} characters, limit {limits.max_chars})")
    if "\x00" in source:
        raise ProgramRejected("program contains a NUL character")
    try:
        tree = ast.parse(source, mode="exec")
    except SyntaxError as exc:
        raise ProgramRejected(f"syntax error: {exc.msg}", exc.lineno or 0) from None
    except (RecursionError, MemoryError, ValueError) as exc:
        raise ProgramRejected(f"program cannot be parsed safely: {type(exc).__name__}") from None
    if len(tree.body) > limits.max_statements:
        raise ProgramRejected(f"too many statements ({len(tree.body)}, limit {limits.max_statements})")
    for count, _node in enumerate(ast.walk(tree), start=1):
        if count > limits.max_nodes:
            raise ProgramRejected(f"program too large (more than {limits.max_nodes} syntax nodes)")
    _check_depth(tree, limits.max_depth)
    for stmt in tree.body:
        _check_statement(stmt)
    return tree


def _check_depth(tree: ast.AST, limit: int) -> None:
    stack: list[tuple[ast.AST, int]] = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > limit:
            raise ProgramRejected(f"expression nested too deeply (limit {limit})", _line(node))
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))


def _check_statement(stmt: ast.stmt) -> None:
    if type(stmt) in _FORBIDDEN_WHY:
        raise ProgramRejected(_FORBIDDEN_WHY[type(stmt)], _line(stmt))
    if not isinstance(stmt, _STATEMENTS):
        raise ProgramRejected(f"{type(stmt).__name__} statements are not allowed", _line(stmt))
    if isinstance(stmt, ast.Assign):
        for target in stmt.targets:
            _check_target(target)
        _check_expr(stmt.value)
    elif isinstance(stmt, ast.AugAssign):
        if not isinstance(stmt.target, ast.Name):
            raise ProgramRejected("augmented assignment only to a plain variable", _line(stmt))
        _check_target(stmt.target)
        if not isinstance(stmt.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            raise ProgramRejected(f"operator {type(stmt.op).__name__} is not allowed", _line(stmt))
        _check_expr(stmt.value)
    elif isinstance(stmt, ast.Expr):
        _check_expr(stmt.value)


def _check_target(target: ast.expr) -> None:
    if isinstance(target, ast.Name):
        _check_name(target.id, target)
        if target.id in _RESERVED:
            raise ProgramRejected(f"{target.id!r} cannot be reassigned", _line(target))
        return
    if isinstance(target, (ast.Tuple, ast.List)):
        for elt in target.elts:
            _check_target(elt)
        return
    raise ProgramRejected("only plain variables can be assigned (no attributes or items)", _line(target))


def _check_expr(node: ast.AST) -> None:
    for sub in ast.walk(node):
        kind = type(sub)
        if kind in _FORBIDDEN_WHY:
            raise ProgramRejected(_FORBIDDEN_WHY[kind], _line(sub))
        if isinstance(sub, ast.expr_context):
            if not isinstance(sub, _CONTEXTS):
                raise ProgramRejected("deleting is not allowed", _line(node))
            continue
        if isinstance(sub, (ast.operator, ast.unaryop, ast.cmpop)):
            if not isinstance(sub, _OPERATORS):
                raise ProgramRejected(f"operator {kind.__name__} is not allowed", _line(node))
            continue
        if not isinstance(sub, _EXPRESSIONS):
            raise ProgramRejected(f"{kind.__name__} is not allowed", _line(sub))
        if isinstance(sub, ast.Name):
            _check_name(sub.id, sub)
        elif isinstance(sub, ast.Attribute):
            _check_attribute(sub)
        elif isinstance(sub, ast.Call):
            _check_call(sub)
        elif isinstance(sub, ast.Constant):
            if not isinstance(sub.value, (int, float, str, bool, type(None))) or isinstance(sub.value, complex):
                raise ProgramRejected(f"constant of type {type(sub.value).__name__} is not allowed", _line(sub))
        elif isinstance(sub, ast.ListComp):
            if len(sub.generators) != 1:
                raise ProgramRejected("only single-loop list comprehensions are allowed", _line(sub))
            gen = sub.generators[0]
            if gen.is_async:
                raise ProgramRejected("async comprehensions are not allowed", _line(sub))
            _check_target(gen.target)
        elif isinstance(sub, ast.FormattedValue):
            if sub.format_spec is not None or sub.conversion not in (-1,):
                raise ProgramRejected("conversions and format specifications in f-strings are not allowed", _line(sub))
        elif isinstance(sub, ast.keyword):
            if sub.arg is None:
                raise ProgramRejected("**keyword expansion is not allowed", _line(node))
            _check_name(sub.arg, node)


def _check_attribute(node: ast.Attribute) -> None:
    _check_name(node.attr, node)
    if isinstance(node.value, ast.Name) and node.value.id == "TurtleBot4Directions":
        if node.attr not in DIRECTIONS:
            raise ProgramRejected(f"TurtleBot4Directions has no member {node.attr!r}", _line(node))
        return
    if isinstance(node.value, ast.Name) and node.value.id == "navigator":
        if node.attr not in ALLOWED_METHODS:
            raise ProgramRejected(f"navigator.{node.attr} is not in the allowed methods", _line(node))
        return
    raise ProgramRejected(
        "attribute access is only allowed as navigator.<method> or TurtleBot4Directions.<member>", _line(node)
    )


def _check_call(node: ast.Call) -> None:
    func = node.func
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id == "navigator":
        if func.attr not in ALLOWED_METHODS:
            raise ProgramRejected(f"navigator.{func.attr}() is not in the allowed methods", _line(node))
        return
    if isinstance(func, ast.Name) and func.id == "getPoseStamped":
        return
    name = func.id if isinstance(func, ast.Name) else ast.unparse(func)[:60]
    raise ProgramRejected(f"call to {name}() is not allowed (only navigator.<allowed method>)", _line(node))


# --------------------------------------------------------------------------------------------------------------
# Stage 2: planning (our own interpreter over pure data)
# --------------------------------------------------------------------------------------------------------------


class _Navigator:
    """Marker value for the name `navigator` inside a program."""


class _Directions:
    """Marker value for the name `TurtleBot4Directions` inside a program."""


_NAVIGATOR = _Navigator()
_DIRECTIONS = _Directions()

PoseCheck = Callable[[float, float], "str | None"]


class _Planner:
    def __init__(
        self, destinations: Mapping[str, Sequence[float]], check_pose: PoseCheck | None, limits: Limits
    ) -> None:
        self.limits = limits
        self.check_pose = check_pose
        self.ops = 0
        self.steps: list[Step] = []
        self.goals = 0
        dest_copy = {str(k): [float(v) for v in val] for k, val in destinations.items()}
        self.env: dict[str, Any] = {
            "navigator": _NAVIGATOR,
            "TurtleBot4Directions": _DIRECTIONS,
            "destinations": dest_copy,
        }

    # -- values -----------------------------------------------------------------------------------------------
    def _tick(self, node: ast.AST) -> None:
        self.ops += 1
        if self.ops > self.limits.max_eval_ops:
            raise ProgramRejected(f"program does too much work (more than {self.limits.max_eval_ops} operations)")

    def _bounded(self, value: Any, node: ast.AST) -> Any:
        lim = self.limits
        if isinstance(value, bool) or value is None:
            return value
        if isinstance(value, (int, float)):
            if isinstance(value, float) and not math.isfinite(value):
                raise ProgramRejected(f"number is not finite ({value})", _line(node))
            if abs(value) > lim.max_abs_number:
                raise ProgramRejected(f"number {value:g} is too large (limit {lim.max_abs_number:g})", _line(node))
            return value
        if isinstance(value, str):
            if len(value) > lim.max_string:
                raise ProgramRejected(f"string too long (limit {lim.max_string})", _line(node))
            return value
        if isinstance(value, (list, tuple)):
            if len(value) > lim.max_list:
                raise ProgramRejected(f"list too long ({len(value)}, limit {lim.max_list})", _line(node))
            return value
        return value

    def run(self, tree: ast.Module) -> Plan:
        for stmt in tree.body:
            self._tick(stmt)
            if isinstance(stmt, ast.Assign):
                value = self.eval(stmt.value)
                for target in stmt.targets:
                    self._assign(target, value, stmt)
            elif isinstance(stmt, ast.AugAssign):
                assert isinstance(stmt.target, ast.Name)
                if stmt.target.id not in self.env:
                    raise ProgramRejected(f"name {stmt.target.id!r} is not defined", _line(stmt))
                current = self.env[stmt.target.id]
                self.env[stmt.target.id] = self._binop(stmt.op, current, self.eval(stmt.value), stmt)
            elif isinstance(stmt, ast.Expr):
                self.eval(stmt.value)
        return Plan(tuple(self.steps), self.goals)

    def _assign(self, target: ast.expr, value: Any, node: ast.AST) -> None:
        if isinstance(target, ast.Name):
            self.env[target.id] = value
            return
        assert isinstance(target, (ast.Tuple, ast.List))
        if not isinstance(value, (list, tuple)) or len(value) != len(target.elts):
            raise ProgramRejected("cannot unpack: the number of values does not match", _line(node))
        for t, v in zip(target.elts, value, strict=True):
            self._assign(t, v, node)

    def eval(self, node: ast.AST) -> Any:
        self._tick(node)
        if isinstance(node, ast.Constant):
            return self._bounded(node.value, node)
        if isinstance(node, ast.Name):
            if node.id not in self.env:
                raise ProgramRejected(f"name {node.id!r} is not defined", _line(node))
            return self.env[node.id]
        if isinstance(node, (ast.List, ast.Tuple)):
            items = [self.eval(e) for e in node.elts]
            return self._bounded(items if isinstance(node, ast.List) else tuple(items), node)
        if isinstance(node, ast.Dict):
            if len(node.keys) > self.limits.max_list:
                raise ProgramRejected("dictionary too large", _line(node))
            out: dict[Any, Any] = {}
            for k, v in zip(node.keys, node.values, strict=True):
                if k is None:
                    raise ProgramRejected("** in dictionaries is not allowed", _line(node))
                key = self.eval(k)
                if not isinstance(key, (str, int, float, bool)):
                    raise ProgramRejected("dictionary keys must be numbers or strings", _line(node))
                out[key] = self.eval(v)
            return out
        if isinstance(node, ast.UnaryOp):
            operand = self.eval(node.operand)
            if not _is_number(operand):
                raise ProgramRejected("unary minus/plus only on numbers", _line(node))
            return self._bounded(-operand if isinstance(node.op, ast.USub) else +operand, node)
        if isinstance(node, ast.BinOp):
            return self._binop(node.op, self.eval(node.left), self.eval(node.right), node)
        if isinstance(node, ast.Compare):
            return self._compare(node)
        if isinstance(node, ast.Subscript):
            return self._subscript(node)
        if isinstance(node, ast.Attribute):
            base = self.eval(node.value)
            if base is _DIRECTIONS:
                return DIRECTIONS[node.attr]
            raise ProgramRejected(f"{ast.unparse(node)} can only be called", _line(node))
        if isinstance(node, ast.Call):
            return self._call(node)
        if isinstance(node, ast.ListComp):
            return self._listcomp(node)
        if isinstance(node, ast.JoinedStr):
            parts = []
            for value in node.values:
                if isinstance(value, ast.Constant):
                    parts.append(str(value.value))
                else:
                    assert isinstance(value, ast.FormattedValue)
                    parts.append(_text(self.eval(value.value)))
            return self._bounded("".join(parts), node)
        raise ProgramRejected(f"{type(node).__name__} is not allowed", _line(node))

    def _binop(self, op: ast.operator, left: Any, right: Any, node: ast.AST) -> Any:
        if _is_number(left) and _is_number(right):
            if isinstance(op, ast.Add):
                result = left + right
            elif isinstance(op, ast.Sub):
                result = left - right
            elif isinstance(op, ast.Mult):
                result = left * right
            elif isinstance(op, ast.Div):
                if right == 0:
                    raise ProgramRejected("division by zero", _line(node))
                result = left / right
            else:
                raise ProgramRejected(f"operator {type(op).__name__} is not allowed", _line(node))
            return self._bounded(result, node)
        if isinstance(op, ast.Add) and isinstance(left, str) and isinstance(right, str):
            return self._bounded(left + right, node)
        if isinstance(op, ast.Add) and isinstance(left, list) and isinstance(right, list):
            return self._bounded(left + right, node)
        raise ProgramRejected(
            f"operator {type(op).__name__} not allowed between {_kind(left)} and {_kind(right)}", _line(node)
        )

    def _compare(self, node: ast.Compare) -> bool:
        left = self.eval(node.left)
        for op, comparator in zip(node.ops, node.comparators, strict=True):
            right = self.eval(comparator)
            if not (_is_plain(left) and _is_plain(right)):
                raise ProgramRejected("comparisons only between numbers or strings", _line(node))
            try:
                ok = {
                    ast.Eq: lambda a, b: a == b,
                    ast.NotEq: lambda a, b: a != b,
                    ast.Lt: lambda a, b: a < b,
                    ast.LtE: lambda a, b: a <= b,
                    ast.Gt: lambda a, b: a > b,
                    ast.GtE: lambda a, b: a >= b,
                }[type(op)](left, right)
            except TypeError:
                raise ProgramRejected("cannot compare these values", _line(node)) from None
            if not ok:
                return False
            left = right
        return True

    def _subscript(self, node: ast.Subscript) -> Any:
        base = self.eval(node.value)
        if isinstance(node.slice, ast.Slice):
            if not isinstance(base, (list, tuple, str)):
                raise ProgramRejected(f"cannot slice a {_kind(base)}", _line(node))
            bounds = []
            for part in (node.slice.lower, node.slice.upper, node.slice.step):
                value = None if part is None else self.eval(part)
                if value is not None and (not isinstance(value, int) or isinstance(value, bool)):
                    raise ProgramRejected("slice bounds must be integers", _line(node))
                bounds.append(value)
            if bounds[2] == 0:
                raise ProgramRejected("slice step cannot be zero", _line(node))
            return base[slice(*bounds)]
        key = self.eval(node.slice)
        if isinstance(base, dict):
            if not isinstance(key, (str, int, float, bool)) or key not in base:
                if base is self.env["destinations"]:
                    known = ", ".join(repr(k) for k in base)
                    raise ProgramRejected(f"unknown destination {key!r} (known: {known})", _line(node))
                raise ProgramRejected(f"key {key!r} not found", _line(node))
            value = base[key]
            return list(value) if isinstance(value, list) else value
        if isinstance(base, (list, tuple, str)):
            if not isinstance(key, int) or isinstance(key, bool):
                raise ProgramRejected("list indices must be integers", _line(node))
            if not -len(base) <= key < len(base):
                raise ProgramRejected(f"index {key} out of range", _line(node))
            return base[key]
        raise ProgramRejected(f"cannot index a {_kind(base)}", _line(node))

    def _listcomp(self, node: ast.ListComp) -> list[Any]:
        gen = node.generators[0]
        iterable = self.eval(gen.iter)
        if isinstance(iterable, dict):
            iterable = list(iterable)
        if not isinstance(iterable, (list, tuple)):
            raise ProgramRejected(f"can only iterate over a list, not a {_kind(iterable)}", _line(node))
        saved = dict(self.env)
        out: list[Any] = []
        try:
            for item in iterable:
                self._assign(gen.target, item, node)
                if all(self.eval(cond) for cond in gen.ifs):
                    out.append(self.eval(node.elt))
                    self._bounded(out, node)
        finally:
            self.env = saved
        return out

    def _call(self, node: ast.Call) -> Any:
        func = node.func
        method = func.attr if isinstance(func, ast.Attribute) else "getPoseStamped"
        spec = ALLOWED_METHODS[method]
        args = [self.eval(a) for a in node.args]
        kwargs = {kw.arg: self.eval(kw.value) for kw in node.keywords if kw.arg is not None}
        bound = _bind(method, spec, args, kwargs, node)
        line = _line(node)
        if method == "getPoseStamped":
            return self._pose(bound["position"], bound["rotation"], node)
        for name, (lo, hi) in spec.bounds.items():
            value = bound[name]
            if not _is_number(value) or not math.isfinite(value) or not lo <= value <= hi:
                raise ProgramRejected(
                    f"navigator.{method}: {name}={value!r} must be a number in [{lo:g}, {hi:g}]", line
                )
        if method == "startToPose":
            pose = bound["pose"]
            if not isinstance(pose, Pose):
                raise ProgramRejected("navigator.startToPose needs a pose from navigator.getPoseStamped", line)
            self._add_goals(1, node)
            self._check(pose, node)
            self._add_step(Step(method, (pose,), line))
        elif method in ("startThroughPoses", "startFollowWaypoints"):
            poses = bound["poses"]
            if not isinstance(poses, (list, tuple)) or not poses or not all(isinstance(p, Pose) for p in poses):
                raise ProgramRejected(f"navigator.{method} needs a non-empty list of poses from getPoseStamped", line)
            self._add_goals(len(poses), node)
            for pose in poses:
                self._check(pose, node)
            self._add_step(Step(method, (list(poses),), line))
        elif method in ("info", "warn", "error", "debug"):
            message = "".join(c if c.isprintable() else " " for c in _text(bound["msg"]))
            self._add_step(Step(method, (message[: self.limits.max_string],), line))
        else:
            self._add_step(Step(method, tuple(bound[name] for name, _ in spec.params), line))
        return None

    def _add_step(self, step: Step) -> None:
        if len(self.steps) >= self.limits.max_steps:
            raise ProgramRejected(f"too many robot actions (limit {self.limits.max_steps})", step.line)
        self.steps.append(step)

    def _add_goals(self, n: int, node: ast.AST) -> None:
        self.goals += n
        if self.goals > self.limits.max_goals:
            raise ProgramRejected(f"too many goals ({self.goals}, limit {self.limits.max_goals})", _line(node))

    def _pose(self, position: Any, rotation: Any, node: ast.AST) -> Pose:
        if not isinstance(position, (list, tuple)) or len(position) != 2 or not all(_is_number(v) for v in position):
            raise ProgramRejected(f"getPoseStamped: position must be [x, y] numbers, got {position!r:.80}", _line(node))
        if not _is_number(rotation):
            raise ProgramRejected(f"getPoseStamped: rotation must be a number of degrees, got {rotation!r:.80}")
        x, y, deg = float(position[0]), float(position[1]), float(rotation)
        for v in (x, y, deg):
            if not math.isfinite(v):
                raise ProgramRejected(f"getPoseStamped: coordinates must be finite, got ({x}, {y}, {deg})", _line(node))
        return Pose(x, y, deg)

    def _check(self, pose: Pose, node: ast.AST) -> None:
        if self.check_pose is None:
            return
        problem = self.check_pose(pose.x, pose.y)
        if problem:
            raise ProgramRejected(f"goal ({pose.x:g}, {pose.y:g}) refused: {problem}", _line(node))


def _bind(method: str, spec: _MethodSpec, args: list[Any], kwargs: dict[str, Any], node: ast.AST) -> dict[str, Any]:
    names = [n for n, _ in spec.params]
    if len(args) > len(names):
        raise ProgramRejected(f"navigator.{method} takes at most {len(names)} arguments, got {len(args)}", _line(node))
    bound = dict(zip(names, args, strict=False))
    for key, value in kwargs.items():
        if key not in names:
            raise ProgramRejected(f"navigator.{method} has no parameter {key!r}", _line(node))
        if key in bound:
            raise ProgramRejected(f"navigator.{method}: {key} given twice", _line(node))
        bound[key] = value
    for name, default in spec.params:
        if name not in bound:
            if default is _REQUIRED:
                raise ProgramRejected(f"navigator.{method} is missing {name!r}", _line(node))
            bound[name] = default
    return bound


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_plain(value: Any) -> bool:
    return isinstance(value, (int, float, str, bool)) or value is None


def _kind(value: Any) -> str:
    if isinstance(value, Pose):
        return "pose"
    if value is _NAVIGATOR:
        return "navigator"
    return type(value).__name__


def _text(value: Any) -> str:
    if isinstance(value, Pose):
        return f"({value.x:g}, {value.y:g}, {value.degrees:g}°)"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    if value is _NAVIGATOR or value is _DIRECTIONS:
        return _kind(value)
    return str(value)


def plan_program(
    source: str,
    destinations: Mapping[str, Sequence[float]] | None = None,
    check_pose: PoseCheck | None = None,
    limits: Limits = Limits(),
) -> Plan:
    """Validate and evaluate a program into a checked Plan; raise ProgramRejected if anything is wrong.

    `destinations` maps names to [x, y, degrees]; `check_pose(x, y)` returns a problem text or None.
    """
    tree = validate(source, limits)
    try:
        return _Planner(destinations or {}, check_pose, limits).run(tree)
    except ProgramRejected:
        raise
    except RecursionError:
        raise ProgramRejected("program nests too deeply") from None
    except Exception as exc:  # noqa: BLE001 - any surprise in evaluation refuses the program, nothing has run
        raise ProgramRejected(f"program could not be evaluated: {type(exc).__name__}: {exc}") from None


# --------------------------------------------------------------------------------------------------------------
# Stage 3: execution on the navigator
# --------------------------------------------------------------------------------------------------------------


def execute_plan(
    plan: Plan,
    navigator: Any,
    limits: Limits = Limits(),
    should_stop: Callable[[], bool] | None = None,
) -> ExecutionReport:
    """Replay a checked plan on the navigator under a wall-clock budget.

    Poses become PoseStamped through navigator.getPoseStamped. spin/backup/driveOnHeading start a task upstream
    and return at once, so we wait (bounded) for isTaskComplete. When the budget is spent a watchdog calls
    cancelTask() on the running task and no further step runs. A step that fails (a goal that does not succeed,
    a dock that does not dock) stops the plan: the next steps assumed it had worked.
    """
    report = ExecutionReport(total=len(plan.steps))
    expired = threading.Event()
    finished = threading.Event()

    def watchdog() -> None:
        if not finished.wait(limits.max_run_seconds):
            expired.set()
            with contextlib.suppress(Exception):  # best effort: the navigator may be between tasks
                navigator.cancelTask()

    timer = threading.Thread(target=watchdog, name="program-watchdog", daemon=True)
    timer.start()
    try:
        for step in plan.steps:
            if expired.is_set():
                report.stopped = f"run-time limit of {limits.max_run_seconds:g} s reached"
                break
            if should_stop is not None and should_stop():
                report.stopped = "stopped on request"
                break
            failure = _run_step(step, navigator, limits, expired)
            if failure:
                report.stopped = failure
                break
            report.completed += 1
        if expired.is_set() and not report.stopped:
            report.stopped = f"run-time limit of {limits.max_run_seconds:g} s reached"
    finally:
        finished.set()
    return report


def _stamped(navigator: Any, pose: Pose) -> Any:
    return navigator.getPoseStamped([pose.x, pose.y], pose.degrees)


def _run_step(step: Step, navigator: Any, limits: Limits, expired: threading.Event) -> str:
    """Run one step; returns why it failed ('' when it did not, or when the navigator does not say)."""
    method = step.method
    if method not in ALLOWED_METHODS:  # plans only come from the planner; belt and braces
        raise ProgramRejected(f"method {method!r} is not allowed")
    if method == "startToPose":
        return _failure(step, navigator.startToPose(_stamped(navigator, step.args[0])))
    if method in ("startThroughPoses", "startFollowWaypoints"):
        return _failure(step, getattr(navigator, method)([_stamped(navigator, p) for p in step.args[0]]))
    if method in _TASK_METHODS:
        started = getattr(navigator, method)(*step.args)
        if not started:  # None (Kilted) or False (Jazzy-era navigators): rejected
            return f"{step.describe()} was rejected"
        deadline = time.monotonic() + limits.task_wait_seconds
        while not navigator.isTaskComplete():
            if expired.is_set() or time.monotonic() > deadline:
                navigator.cancelTask()
                break
        return ""
    result = getattr(navigator, method)(*step.args)
    if method in ("dock", "undock") and result is False:
        return f"{method} did not succeed"
    return ""


def _failure(step: Step, result: Any) -> str:
    """Upstream's start* return None; ours return a TaskResult (SUCCEEDED = 1): anything else stops the plan."""
    if result is None or isinstance(result, bool):
        return "" if result is not False else f"{step.describe()} did not succeed"
    try:
        code = int(result)
    except (TypeError, ValueError):
        return ""
    if code == 1:
        return ""
    name = getattr(result, "name", str(code))
    return f"{step.describe()} ended {name}"


def run_program(
    source: str,
    navigator: Any,
    destinations: Mapping[str, Sequence[float]] | None = None,
    check_pose: PoseCheck | None = None,
    limits: Limits = Limits(),
) -> tuple[Plan, ExecutionReport]:
    """Plan (raising ProgramRejected with nothing executed) and then execute a program."""
    plan = plan_program(source, destinations, check_pose, limits)
    return plan, execute_plan(plan, navigator, limits)
