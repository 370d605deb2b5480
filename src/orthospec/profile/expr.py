"""A small, safe expression grammar for profiles.

Grammar (parsed with :mod:`ast` in ``eval`` mode and *interpreted* over a whitelist; nothing is
ever compiled or executed):

    expr    := or
    or      := and ('or' and)*
    and     := not ('and' not)*
    not     := 'not' not | cmp
    cmp     := arith (('<'|'<='|'>'|'>='|'=='|'!=') arith)*
    arith   := term (('+'|'-') term)*
    term    := unary (('*'|'/'|'%') unary)*
    unary   := ('-'|'+') unary | power
    power   := atom ('**' unary)?
    atom    := NUMBER | STRING | 'true' | 'false' | NAME ('.' NAME)* | call | '(' expr ')'
    call    := ('min'|'max'|'abs') '(' expr (',' expr)* ')'
             | ('sin'|'cos'|'tan'|'atan') '(' expr ')' | 'atan2' '(' expr ',' expr ')'

Names resolve through a caller-given mapping: parameters, manifest paths (``manifest.sensor.type``)
and measures of the rule's scope. In comparisons and in + and -, a bare number takes the unit of
the other side: ``images.roll > 1`` reads 1 deg, ``cloud_cover < 5`` reads 5 %. Values may be
numbers, strings, booleans, numpy arrays or pint
quantities, so one expression evaluates a whole column at once (vectorised).

Trigonometry keeps its units (issue 26: JRC Figure 2, dx = dh x tan(off-nadir angle)):
``sin``, ``cos`` and ``tan`` take an angle with its unit (a measure or parameter in deg or rad;
a bare number or a length is refused, since nothing says whether 17 means degrees) and give a
pure number; ``atan(ratio)`` and ``atan2(y, x)`` give an angle in degrees (``atan`` of a pure
number or of a ratio whose units cancel, ``atan2`` of two values of one dimension).

Limits (issue 17: a profile may come from anyone, and ``9**9**9`` or ``'a' * 10**10`` must not hang
or exhaust memory). Checked when the expression is parsed, so ``spec validate`` refuses them with
the location: at most ``MAX_LENGTH`` characters, ``MAX_DEPTH`` levels of nesting, ``MAX_ARGS``
arguments to min()/max(), integer literals up to ``MAX_INT``, an exponent that is a number
(|e| <= ``MAX_EXPONENT``) or a single name, and no string times anything. Checked while
evaluating, before each operation: an exponent above ``MAX_EXPONENT``, an integer result beyond
``MAX_INT_BITS`` bits, string repetition, and ``MAX_STEPS`` operations or ``MAX_SECONDS`` per
evaluation.
"""

from __future__ import annotations

import ast
import operator
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from ..dotted import dotted_name as _dotted
from ..errors import ExpressionError

_BIN: dict[type, Callable[[Any, Any], Any]] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Mod: operator.mod,
    ast.Pow: operator.pow,
}
_CMP: dict[type, Callable[[Any, Any], Any]] = {
    ast.Lt: operator.lt,
    ast.LtE: operator.le,
    ast.Gt: operator.gt,
    ast.GtE: operator.ge,
    ast.Eq: operator.eq,
    ast.NotEq: operator.ne,
}
_CMP_TEXT = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!="}
_FUNCS = {"min", "max", "abs", "sin", "cos", "tan", "atan", "atan2"}
#: functions of a fixed number of arguments (min and max take 1 to MAX_ARGS)
_ARITY = {"abs": 1, "sin": 1, "cos": 1, "tan": 1, "atan": 1, "atan2": 2}
_TRIG = {"sin": np.sin, "cos": np.cos, "tan": np.tan}
_CONSTS = {"true": True, "false": False, "True": True, "False": False, "null": None, "None": None}
MAX_LENGTH = 500
MAX_DEPTH = 32
MAX_ARGS = 16
MAX_INT = 10**18
MAX_EXPONENT = 64
MAX_INT_BITS = 256
MAX_STEPS = 10_000
MAX_SECONDS = 5.0


@dataclass(frozen=True)
class Expression:
    """A parsed expression; evaluate it with :meth:`evaluate`."""

    source: str
    tree: ast.AST
    names: frozenset[str]

    def evaluate(self, names: Mapping[str, Any]) -> Any:
        return _Eval(names, self.source).visit(self.tree)


@lru_cache(maxsize=2048)
def parse(source: str) -> Expression:
    """Parse ``source`` or raise ExpressionError saying what is not allowed."""
    if not isinstance(source, str) or not source.strip():
        raise ExpressionError("empty expression")
    if len(source) > MAX_LENGTH:
        raise ExpressionError(f"expression longer than {MAX_LENGTH} characters")
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(
            f"invalid expression {source!r}: {exc.msg} at column {exc.offset}"
        ) from None
    names: set[str] = set()
    _check(tree.body, source, names)
    return Expression(source, tree.body, frozenset(names))


def _number(node: ast.AST) -> float | int | None:
    """The value of a (signed) number literal, else None."""
    sign = 1
    while isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        sign = -sign if isinstance(node.op, ast.USub) else sign
        node = node.operand
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, int | float)
        and not isinstance(node.value, bool)
    ):
        return sign * node.value
    return None


def _check(node: ast.AST, src: str, names: set[str], depth: int = 0) -> None:
    bad = f"not allowed in expression {src!r}"
    if depth > MAX_DEPTH:
        raise ExpressionError(f"expression {src!r} is nested more than {MAX_DEPTH} levels deep")
    _limits(node, src)
    _check_node(node, src, names, depth, bad)


def _limits(node: ast.AST, src: str) -> None:
    """The resource limits of the grammar, per node (see the module docstring)."""
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
        e = node.right
        n = _number(e)
        if n is None and not isinstance(e, ast.Name | ast.Attribute):
            raise ExpressionError(f"the exponent of ** must be a number or a name, in {src!r}")
        if n is not None and abs(n) > MAX_EXPONENT:
            raise ExpressionError(f"exponent {n!r} is larger than {MAX_EXPONENT} in {src!r}")
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult | ast.Mod):
        for side in (node.left, node.right):
            if isinstance(side, ast.Constant) and isinstance(side.value, str):
                raise ExpressionError(
                    f"string repetition and formatting ('text' * n, 'text' % x) "
                    f"are not allowed in {src!r}"
                )
    if (
        isinstance(node, ast.Constant)
        and isinstance(node.value, int)
        and not isinstance(node.value, bool)
        and abs(node.value) > MAX_INT
    ):
        raise ExpressionError(
            f"integer {str(node.value)[:30]} is larger than {MAX_INT:.0e} in {src!r}"
        )
    if isinstance(node, ast.Call) and len(node.args) > MAX_ARGS:
        raise ExpressionError(f"{len(node.args)} arguments: at most {MAX_ARGS} in {src!r}")


def _check_node(node: ast.AST, src: str, names: set[str], depth: int, bad: str) -> None:
    d = depth + 1
    if isinstance(node, ast.BoolOp):
        for v in node.values:
            _check(v, src, names, d)
    elif isinstance(node, ast.UnaryOp):
        if not isinstance(node.op, ast.Not | ast.USub | ast.UAdd):
            raise ExpressionError(f"operator {type(node.op).__name__} {bad}")
        _check(node.operand, src, names, d)
    elif isinstance(node, ast.BinOp):
        if type(node.op) not in _BIN:
            raise ExpressionError(f"operator {type(node.op).__name__} {bad}")
        _check(node.left, src, names, d)
        _check(node.right, src, names, d)
    elif isinstance(node, ast.Compare):
        for op in node.ops:
            if type(op) not in _CMP:
                raise ExpressionError(f"comparison {type(op).__name__} {bad}")
        _check(node.left, src, names, d)
        for c in node.comparators:
            _check(c, src, names, d)
    elif isinstance(node, ast.Call):
        fname = node.func.id if isinstance(node.func, ast.Name) else None
        if fname not in _FUNCS or node.keywords or not node.args:
            raise ExpressionError(
                f"only {', '.join(f + '()' for f in sorted(_FUNCS))} calls are allowed in {src!r}"
            )
        if fname in _ARITY and len(node.args) != _ARITY[fname]:
            n = _ARITY[fname]
            raise ExpressionError(f"{fname}() takes {n} argument{'s' if n > 1 else ''} in {src!r}")
        for a in node.args:
            if isinstance(a, ast.Starred):
                raise ExpressionError(f"*args {bad}")
            _check(a, src, names, d)
    elif isinstance(node, ast.Constant):
        if not isinstance(node.value, int | float | str | bool) and node.value is not None:
            raise ExpressionError(f"constant {node.value!r} {bad}")
    elif isinstance(node, ast.Name | ast.Attribute):
        dotted = _dotted(node)
        if dotted is None:
            raise ExpressionError(f"attribute access on a non-name {bad}")
        if any(part.startswith("_") for part in dotted.split(".")):
            raise ExpressionError(f"names starting with '_' are {bad}")
        if dotted not in _CONSTS:
            names.add(dotted)
    else:
        raise ExpressionError(f"{type(node).__name__} {bad}")


class _Eval:
    def __init__(self, names: Mapping[str, Any], src: str) -> None:
        self.names, self.src = names, src
        self.steps = 0
        self.deadline = time.perf_counter() + MAX_SECONDS

    def visit(self, node: ast.AST) -> Any:
        self.steps += 1
        if self.steps > MAX_STEPS or time.perf_counter() > self.deadline:
            raise ExpressionError(
                f"evaluation budget exceeded ({MAX_STEPS} steps or {MAX_SECONDS:g} s) "
                f"in {self.src!r}"
            )
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name | ast.Attribute):
            dotted = _dotted(node)
            assert dotted is not None
            if dotted in _CONSTS:
                return _CONSTS[dotted]
            if dotted not in self.names:
                raise ExpressionError(f"unknown name {dotted!r} in {self.src!r}")
            return self.names[dotted]
        if isinstance(node, ast.BoolOp):
            vals = [self.visit(v) for v in node.values]
            fn = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
            out = vals[0]
            for v in vals[1:]:
                out = fn(_truth(out), _truth(v))
            return _scalar(out)
        if isinstance(node, ast.UnaryOp):
            v = self.visit(node.operand)
            if isinstance(node.op, ast.Not):
                return _scalar(np.logical_not(_truth(v)))
            return -v if isinstance(node.op, ast.USub) else +v
        if isinstance(node, ast.BinOp):
            return self._arith(_BIN[type(node.op)], self.visit(node.left), self.visit(node.right))
        if isinstance(node, ast.Compare):
            left = self.visit(node.left)
            result: Any = True
            for op, comp in zip(node.ops, node.comparators, strict=True):
                right = self.visit(comp)
                result = np.logical_and(result, self._arith(_CMP[type(op)], left, right))
                left = right
            return _scalar(result)
        if isinstance(node, ast.Call):
            fname = node.func.id  # type: ignore[attr-defined]
            args = [self.visit(a) for a in node.args]
            if fname == "abs":
                return abs(args[0])
            if fname in _TRIG:
                return _TRIG[fname](_radians(args[0], fname, self.src))
            if fname in ("atan", "atan2"):
                return _arctan(fname, args, self.src)
            out = args[0]
            for a in args[1:]:
                pick = self._arith(operator.lt if fname == "min" else operator.gt, a, out)
                out = _where(pick, a, out)
            return out
        raise ExpressionError(f"cannot evaluate {type(node).__name__} in {self.src!r}")

    def _arith(self, fn: Callable[[Any, Any], Any], a: Any, b: Any) -> Any:
        if fn in _SAME_UNIT:
            a, b = _coerce_bare(a, b)
        self._bounded(fn, a, b)
        try:
            out = fn(a, b)
            if (
                isinstance(out, int)
                and not isinstance(out, bool)
                and out.bit_length() > MAX_INT_BITS
            ):
                raise ExpressionError(
                    f"integer result larger than {MAX_INT_BITS} bits in {self.src!r}"
                )
            return out
        except ExpressionError:
            raise
        except ZeroDivisionError:
            raise ExpressionError(f"division by zero in {self.src!r}") from None
        except (TypeError, ValueError, ArithmeticError, AttributeError) as exc:
            # pint's DimensionalityError/OffsetUnitCalculusError are TypeErrors, UndefinedUnitError an
            # AttributeError; str vs number a TypeError: all become one ExpressionError (cause kept)
            raise ExpressionError(
                f"cannot combine {_show(a)} and {_show(b)} in {self.src!r}: {exc}"
            ) from exc

    def _bounded(self, fn: Callable[[Any, Any], Any], a: Any, b: Any) -> None:
        """Refuse, before computing, an operation whose result could exhaust time or memory."""
        if fn is operator.mul and any(isinstance(v, str | bytes | list | tuple) for v in (a, b)):
            raise ExpressionError(f"string repetition is not allowed in {self.src!r}")
        if fn is operator.mod and isinstance(a, str | bytes):
            raise ExpressionError(f"string formatting is not allowed in {self.src!r}")
        if fn is operator.pow:
            e = np.asarray(getattr(b, "magnitude", b))
            if e.dtype.kind in "fiu" and e.size and float(np.nanmax(np.abs(e))) > MAX_EXPONENT:
                raise ExpressionError(f"exponent larger than {MAX_EXPONENT} in {self.src!r}")


#: Operations where a bare number takes the unit of the other side ("roll > 1" with roll in deg
#: means 1 deg, not 1 radian; "cloud < 5" with cloud in % means 5 %). pint alone would read a
#: bare number as dimensionless and convert deg to rad or % to a fraction.
_SAME_UNIT = {operator.add, operator.sub, *_CMP.values()}


def _coerce_bare(a: Any, b: Any) -> tuple[Any, Any]:
    ua, ub = hasattr(a, "units"), hasattr(b, "units")
    if ua and not ub and _is_number(b):
        return a, type(a)(b, a.units)
    if ub and not ua and _is_number(a):
        return type(b)(a, b.units), b
    return a, b


def _is_number(v: Any) -> bool:
    if isinstance(v, bool):
        return False
    if isinstance(v, int | float | np.integer | np.floating):
        return True
    return isinstance(v, np.ndarray) and v.dtype.kind in "fiu"


def _truth(v: Any) -> Any:
    return getattr(v, "magnitude", v)


def _scalar(v: Any) -> Any:
    if isinstance(v, np.ndarray) and v.ndim == 0:
        return bool(v)
    if isinstance(v, np.bool_):
        return bool(v)
    return v


def _where(cond: Any, a: Any, b: Any) -> Any:
    if np.ndim(cond) == 0:
        return a if bool(cond) else b
    if hasattr(a, "units") or hasattr(b, "units"):
        unit = getattr(a, "units", None) or b.units
        am = a.to(unit).magnitude if hasattr(a, "units") else a
        bm = b.to(unit).magnitude if hasattr(b, "units") else b
        return type(a if hasattr(a, "units") else b)(np.where(cond, am, bm), unit)
    return np.where(cond, a, b)


def _radians(v: Any, fname: str, src: str) -> Any:
    """An angle as radians (float or array); anything that is not an angle with a unit is refused."""
    if v is None:
        raise ExpressionError(f"{fname}() of a value that is not given in {src!r}")
    if not hasattr(v, "units"):
        raise ExpressionError(
            f"{fname}() needs an angle with its unit (deg or rad), got {_show(v)} in {src!r}: "
            "name a measure or parameter in degrees"
        )
    try:
        return np.asarray(v.to("radian").magnitude, dtype=float)[()]
    except Exception as exc:  # pint DimensionalityError (a TypeError) or an undefined unit
        raise ExpressionError(
            f"{fname}() needs an angle (deg or rad), got {_show(v)} in {src!r}"
        ) from exc


def _ratio(v: Any, fname: str, src: str) -> Any:
    """A pure number: a bare number, or a quantity whose units cancel (m / m)."""
    if v is None or isinstance(v, bool | str):
        raise ExpressionError(f"{fname}() of {_show(v)} in {src!r}: expected a number")
    if hasattr(v, "units"):
        try:
            return np.asarray(v.to("dimensionless").magnitude, dtype=float)[()]
        except Exception as exc:
            raise ExpressionError(
                f"{fname}() of {_show(v)} in {src!r}: expected a pure number (a ratio whose "
                "units cancel)"
            ) from exc
    return np.asarray(v, dtype=float)[()]


def _arctan(fname: str, args: list[Any], src: str) -> Any:
    """atan(ratio) or atan2(y, x), as an angle in degrees."""
    from .. import units

    if fname == "atan":
        rad = np.arctan(_ratio(args[0], fname, src))
    else:
        y, x = args
        if hasattr(y, "units") or hasattr(x, "units"):
            try:
                unit = (y if hasattr(y, "units") else x).units
                y = np.asarray(y.to(unit).magnitude if hasattr(y, "units") else y, dtype=float)
                x = np.asarray(x.to(unit).magnitude if hasattr(x, "units") else x, dtype=float)
            except Exception as exc:
                raise ExpressionError(
                    f"atan2() of {_show(args[0])} and {_show(args[1])} in {src!r}: both "
                    "must have one dimension"
                ) from exc
        rad = np.arctan2(_ratio(y, fname, src), _ratio(x, fname, src))
    return units.Q_(np.degrees(rad), "degree")


def _show(v: Any) -> str:
    text = repr(v)
    return text if len(text) < 40 else text[:37] + "..."
