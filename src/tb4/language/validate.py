"""Stage 1, validate: is this text a program in our small language? Static checks only, nothing is evaluated.

Accepted: straight-line code of assignments, literals, arithmetic, comparisons, ``destinations[...]`` look-ups,
``TurtleBot4Directions`` members, single-loop list comprehensions, f-strings without conversions, and calls to
the allow-list of navigator methods. Refused, with the line and the reason: everything else (imports, dunder or
private names, any other call, loops, definitions, ...), and anything Python's own compiler refuses (a repeated
keyword argument, ``return`` outside a function, ...): the language is a subset of Python, never more.
"""

from __future__ import annotations

import ast
import contextlib
import threading
import warnings
from collections.abc import Iterator

from tb4.core.directions import DIRECTIONS
from tb4.language.limits import DEFAULT_LIMITS, Limits
from tb4.language.vocabulary import ALLOWED_METHODS, PlanningError, ProgramRejected

__all__ = ["validate", "RESERVED_NAMES"]

#: Names a program sees and cannot rebind.
RESERVED_NAMES = ("navigator", "TurtleBot4Directions", "destinations")

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


def line_of(node: ast.AST) -> int:
    """The source line of a node (0 when it has none)."""
    return int(getattr(node, "lineno", 0) or 0)


def validate(source: str, limits: Limits = DEFAULT_LIMITS) -> ast.Module:
    """Parse and statically check a program; raise ProgramRejected with the first problem found."""
    if not isinstance(source, str):
        raise ProgramRejected("a program must be text")
    if len(source) > limits.max_chars:
        raise ProgramRejected(f"program too long ({len(source)} characters, limit {limits.max_chars})")
    if "\x00" in source:
        raise ProgramRejected("program contains a NUL character")
    tree = _parse(source)
    if len(tree.body) > limits.max_statements:
        raise ProgramRejected(f"too many statements ({len(tree.body)}, limit {limits.max_statements})")
    for count, _node in enumerate(ast.walk(tree), start=1):
        if count > limits.max_nodes:
            raise ProgramRejected(f"program too large (more than {limits.max_nodes} syntax nodes)")
    _check_depth(tree, limits.max_depth)
    for stmt in tree.body:
        _check_statement(stmt)
    _compile_check(source)
    return tree


# One program parsed or compiled at a time in this process. CPython 3.11's ast module counts its recursion depth in
# state shared by all threads, so two threads in ast.parse at once can fail with "SystemError: AST constructor
# recursion depth mismatch" (python/cpython#106905; stress run s44: one of sixteen planning threads); and
# warnings.catch_warnings() swaps process-wide filters. Parsing a program within the size limits takes milliseconds.
_PARSE_LOCK = threading.Lock()


@contextlib.contextmanager
def _python_compiler() -> Iterator[None]:
    """Hold the parse lock, with the compiler's warnings silenced (e.g. SyntaxWarning for invalid escapes: not our
    business)."""
    with _PARSE_LOCK, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield


def _parse(source: str) -> ast.Module:
    try:
        with _python_compiler():
            return ast.parse(source, mode="exec")
    except SyntaxError as exc:
        raise ProgramRejected(f"syntax error: {exc.msg}", exc.lineno or 0) from None
    except ValueError as exc:  # e.g. an integer literal beyond int_max_str_digits
        raise ProgramRejected(f"program cannot be parsed: {type(exc).__name__}") from None
    except RecursionError:
        raise ProgramRejected("program nests too deeply to be parsed") from None
    except MemoryError:
        raise PlanningError("out of memory", "while parsing the program") from None


def _compile_check(source: str) -> None:
    """Refuse what CPython's compiler refuses after parsing (repeated keywords and the like). The code object
    is thrown away: it is never executed. Constant folding in the compiler is size-limited by CPython."""
    try:
        with _python_compiler():
            compile(source, "<program>", "exec", dont_inherit=True)
    except SyntaxError as exc:
        raise ProgramRejected(f"Python refuses this program: {exc.msg}", exc.lineno or 0) from None
    except (ValueError, OverflowError) as exc:
        raise ProgramRejected(f"Python refuses this program: {type(exc).__name__}") from None
    except RecursionError:
        raise ProgramRejected("program nests too deeply to be compiled") from None
    except MemoryError:
        raise PlanningError("out of memory", "while compiling the program") from None


def _check_name(name: str, node: ast.AST) -> None:
    if name.startswith("_"):
        raise ProgramRejected(f"private or dunder name {name[:40]!r} is not allowed", line_of(node))


def _check_depth(tree: ast.AST, limit: int) -> None:
    stack: list[tuple[ast.AST, int]] = [(tree, 0)]
    while stack:
        node, depth = stack.pop()
        if depth > limit:
            raise ProgramRejected(f"expression nested too deeply (limit {limit})", line_of(node))
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))


def _check_statement(stmt: ast.stmt) -> None:
    if type(stmt) in _FORBIDDEN_WHY:
        raise ProgramRejected(_FORBIDDEN_WHY[type(stmt)], line_of(stmt))
    if not isinstance(stmt, _STATEMENTS):
        raise ProgramRejected(f"{type(stmt).__name__} statements are not allowed", line_of(stmt))
    if isinstance(stmt, ast.Assign):
        for target in stmt.targets:
            _check_target(target)
        _check_expr(stmt.value)
    elif isinstance(stmt, ast.AugAssign):
        if not isinstance(stmt.target, ast.Name):
            raise ProgramRejected("augmented assignment only to a plain variable", line_of(stmt))
        _check_target(stmt.target)
        if not isinstance(stmt.op, (ast.Add, ast.Sub, ast.Mult, ast.Div)):
            raise ProgramRejected(f"operator {type(stmt.op).__name__} is not allowed", line_of(stmt))
        _check_expr(stmt.value)
    elif isinstance(stmt, ast.Expr):
        _check_expr(stmt.value)


def _check_target(target: ast.expr) -> None:
    if isinstance(target, ast.Name):
        _check_name(target.id, target)
        if target.id in RESERVED_NAMES:
            raise ProgramRejected(f"{target.id!r} cannot be reassigned", line_of(target))
        return
    if isinstance(target, (ast.Tuple, ast.List)):
        for elt in target.elts:
            _check_target(elt)
        return
    raise ProgramRejected("only plain variables can be assigned (no attributes or items)", line_of(target))


def _check_expr(node: ast.AST) -> None:
    for sub in ast.walk(node):
        kind = type(sub)
        if kind in _FORBIDDEN_WHY:
            raise ProgramRejected(_FORBIDDEN_WHY[kind], line_of(sub))
        if isinstance(sub, ast.expr_context):
            if not isinstance(sub, _CONTEXTS):
                raise ProgramRejected("deleting is not allowed", line_of(node))
            continue
        if isinstance(sub, (ast.operator, ast.unaryop, ast.cmpop)):
            if not isinstance(sub, _OPERATORS):
                raise ProgramRejected(f"operator {kind.__name__} is not allowed", line_of(node))
            continue
        if not isinstance(sub, _EXPRESSIONS):
            raise ProgramRejected(f"{kind.__name__} is not allowed", line_of(sub))
        _check_node(sub, node)


def _check_node(sub: ast.AST, node: ast.AST) -> None:
    if isinstance(sub, ast.Name):
        _check_name(sub.id, sub)
    elif isinstance(sub, ast.Attribute):
        _check_attribute(sub)
    elif isinstance(sub, ast.Call):
        _check_call(sub)
    elif isinstance(sub, ast.Constant):
        if not isinstance(sub.value, (int, float, str, bool, type(None))) or isinstance(sub.value, complex):
            raise ProgramRejected(f"constant of type {type(sub.value).__name__} is not allowed", line_of(sub))
    elif isinstance(sub, ast.ListComp):
        if len(sub.generators) != 1:
            raise ProgramRejected("only single-loop list comprehensions are allowed", line_of(sub))
        gen = sub.generators[0]
        if gen.is_async:
            raise ProgramRejected("async comprehensions are not allowed", line_of(sub))
        _check_target(gen.target)
    elif isinstance(sub, ast.FormattedValue):
        if sub.format_spec is not None or sub.conversion != -1:
            raise ProgramRejected("conversions and format specifications in f-strings are not allowed", line_of(sub))
    elif isinstance(sub, ast.keyword):
        if sub.arg is None:
            raise ProgramRejected("**keyword expansion is not allowed", line_of(node))
        _check_name(sub.arg, node)


def _check_attribute(node: ast.Attribute) -> None:
    _check_name(node.attr, node)
    if isinstance(node.value, ast.Name) and node.value.id == "TurtleBot4Directions":
        if node.attr not in DIRECTIONS:
            raise ProgramRejected(f"TurtleBot4Directions has no member {node.attr[:40]!r}", line_of(node))
        return
    if isinstance(node.value, ast.Name) and node.value.id == "navigator":
        if node.attr not in ALLOWED_METHODS:
            raise ProgramRejected(f"navigator.{node.attr[:40]} is not in the allowed methods", line_of(node))
        return
    raise ProgramRejected(
        "attribute access is only allowed as navigator.<method> or TurtleBot4Directions.<member>", line_of(node)
    )


def _check_call(node: ast.Call) -> None:
    func = node.func
    if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id == "navigator":
        if func.attr not in ALLOWED_METHODS:
            raise ProgramRejected(f"navigator.{func.attr[:40]}() is not in the allowed methods", line_of(node))
        return
    if isinstance(func, ast.Name) and func.id == "getPoseStamped":
        return
    name = func.id if isinstance(func, ast.Name) else ast.unparse(func)
    raise ProgramRejected(f"call to {name[:60]}() is not allowed (only navigator.<allowed method>)", line_of(node))
