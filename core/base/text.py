"""Expressions typed as text, read without running them.

Parameters, momenta, impulses and quantities may be given as strings
(``"0.3"``, ``"k*x**2/2"``, ``"1e-3*sin(2*pi*50*t)"``).  They come from
users, files and colleagues' netlists, so they are *data*: this module
reads them with Python's parser into a syntax tree and builds the SymPy
expression from a whitelist — numbers, names, ``+ - * / **``, unary signs,
calls of the functions in :data:`FUNCTIONS`, and ``Piecewise((value,
condition), ...)`` whose conditions compare expressions (``< <= > >=``),
combined with ``& | ~`` and ``True`` (as SymPy writes a pulse).  Nothing in the text is
evaluated by Python (no ``eval``, no ``sympify`` of the string), and sizes
are bounded: the text's length, its nesting, and powers of numbers whose
value would not fit in a float.

Every name that is not called is a plain symbol, except ``pi`` and ``t``
(the time symbol) and names the caller maps (``names=``).

>>> parse_expression("E*beta + sin(2*pi*t)", "a force")
E*beta + sin(2*pi*t)
>>> parse_expression("open('notes.txt', 'w')", "a force")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
lagrangian.errors.ExpressionError: a force: 'open' is not a function an expression may call (known: Abs, abs, acos, ...); write numbers, names, + - * / ** and known functions only.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import ExpressionError
from . import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["parse_expression", "as_expr", "FUNCTIONS", "MAX_LENGTH"]

#: Longest text read as an expression.
MAX_LENGTH = 10_000
#: Deepest nesting of operations and calls.
MAX_DEPTH = 200

class _SymPyNames(Mapping):
    """Names mapped to SymPy's objects of the given names, read from SymPy when asked for (the names alone import
    nothing)."""

    def __init__(self, names: Mapping[Any, str]):
        self._names = dict(names)

    def __getitem__(self, key: Any) -> Any:
        return getattr(sp, self._names[key])

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)


#: Functions an expression may call, by the names it may call them.
FUNCTIONS: Mapping[str, Any] = _SymPyNames({
    **{name: name for name in (
        "sin", "cos", "tan", "cot", "sec", "csc", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
        "asinh", "acosh", "atanh", "exp", "log", "sqrt", "Abs", "sign", "floor", "ceiling", "Heaviside",
        "Min", "Max", "erf", "erfc", "Mod")},
    "abs": "Abs", "ln": "log", "min": "Min", "max": "Max",
})

#: Comparisons a condition of ``Piecewise`` may make, and how conditions combine (``&``, ``|``, ``~``, as SymPy
#: writes them).
_COMPARE = _SymPyNames({ast.Lt: "StrictLessThan", ast.LtE: "LessThan", ast.Gt: "StrictGreaterThan",
                        ast.GtE: "GreaterThan"})
_LOGIC = _SymPyNames({ast.BitAnd: "And", ast.BitOr: "Or"})

_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b, ast.Mult: lambda a, b: a * b,
           ast.Div: lambda a, b: a / b}


def _known() -> str:
    return ", ".join(sorted(FUNCTIONS, key=str.lower))


def parse_expression(text: str, what: str, *, names: Mapping[str, sp.Basic] | None = None) -> sp.Expr:
    """The SymPy expression written in ``text`` (see the module docstring); ``what`` names the argument in errors.

    Raises :class:`~lagrangian.ExpressionError` (a ``ModelError``) saying
    what in the text is not allowed, or why it cannot be read.
    """
    if not isinstance(text, str):
        raise ExpressionError(f"{what}: expected text, got {type(text).__name__}.")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{what}: an expression of {len(text)} characters is longer than {MAX_LENGTH}; build it "
                              f"with SymPy instead.")
    if not text.strip():
        raise ExpressionError(f"{what}: the expression is empty.")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, MemoryError, RecursionError) as exc:
        detail = exc.msg if isinstance(exc, SyntaxError) else type(exc).__name__
        raise ExpressionError(f"{what}: cannot read {_short(text)} as an expression ({detail}).") from None
    return _Reader(what, dict(names or {}), text.strip()).read(tree.body, 0)


def as_expr(value: Any, what: str, *, names: Mapping[str, sp.Basic] | None = None) -> sp.Expr:
    """A number, a SymPy expression or text (read by :func:`parse_expression`) as a SymPy expression.

    Anything else (a bool, a list, an arbitrary object, nan or an infinity) is
    an :class:`~lagrangian.ExpressionError` naming ``what``.

    >>> as_expr(0.3, "m"), as_expr("3/4", "m"), as_expr(sp.Symbol("k"), "m")
    (0.300000000000000, 3/4, k)
    """
    if isinstance(value, str):
        return parse_expression(value, what, names=names)
    if isinstance(value, bool) or value is None:
        raise ExpressionError(f"{what}: expected a number or an expression, got {value!r}.")
    if isinstance(value, (Mapping, list, tuple, set, frozenset, bytes, bytearray, sp.MatrixBase)) or (
            isinstance(value, np.ndarray) and value.ndim > 0):
        # SymPy would read text inside a container as code: containers are never read
        raise ExpressionError(f"{what}: expected a scalar number or expression, got {_short(repr(value))}.")
    try:
        expr = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError, ValueError):
        raise ExpressionError(f"{what}: expected a number or an expression, got {_short(repr(value))}.") from None
    if not isinstance(expr, sp.Expr):
        raise ExpressionError(f"{what}: expected a scalar number or expression, got {_short(repr(value))}.")
    if expr.has(sp.nan, sp.oo, -sp.oo, sp.zoo):
        raise ExpressionError(f"{what}: expected a finite real number or expression, got {_short(repr(value))}.")
    return expr


def _beyond_float(value: sp.Expr) -> bool:
    """Whether ``value`` is a number whose size is beyond a float's (each function of a text is checked as it is
    read, so the arguments of the one checked are within a float's range and its value takes little to evaluate)."""
    if not (isinstance(value, sp.Expr) and value.is_number) or value.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        return False  # log(0) is zoo: not finite, as where it is used says
    try:
        re_, im_ = (float(part) for part in value.evalf(17).as_real_imag())
    except (TypeError, ValueError, ArithmeticError):  # OverflowError; PrecisionExhausted: floor(1e308/pi)
        return False  # not a plain number, or one evalf cannot settle in 17 digits: where it is used judges it
    return not (math.isfinite(re_) and math.isfinite(im_))


def _unparsed(node: ast.AST) -> str:
    """``node`` written back as text for a message; a tree nested too deeply for :func:`ast.unparse` (a chain of a
    thousand ``%``, which ``ast.parse`` reads) is named by its kind."""
    try:
        return ast.unparse(node)
    except RecursionError:
        return "(an operation nested too deeply to show)"


def _short(text: str, width: int = 60) -> str:
    return repr(text if len(text) <= width else text[: width - 3] + "...")


class _Reader:
    def __init__(self, what: str, names: dict, source: str = ""):
        self.what, self.names, self.source = what, names, source

    def refuse(self, message: str):
        raise ExpressionError(f"{self.what}: {message}; write numbers, names, + - * / ** and known functions only.")

    def read(self, node: ast.AST, depth: int) -> sp.Expr:
        if depth > MAX_DEPTH:
            raise ExpressionError(f"{self.what}: the expression nests deeper than {MAX_DEPTH} levels.")
        if isinstance(node, ast.Constant):
            value = node.value
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                self.refuse(f"{value!r} is not a number")
            if isinstance(value, float) and not math.isfinite(value):  # 1e400: Python reads it as inf
                written = ast.get_source_segment(self.source, node) or repr(value)
                raise ExpressionError(f"{self.what}: the number {_short(written, 40)} is not finite: it is beyond a "
                                      f"float's range (±1.8e308); write a smaller number, or the value in larger units.")
            return sp.Integer(value) if isinstance(value, int) else sp.Float(value)
        if isinstance(node, ast.Name):
            if node.id in self.names:
                return self.names[node.id]
            if node.id == "pi":
                return sp.pi
            if node.id == "t":
                return _deferred.time_symbol()  # lagrangian.t
            if node.id in FUNCTIONS:
                self.refuse(f"{node.id!r} is a function: call it, as {node.id}(x)")
            return sp.Symbol(node.id)
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            inner = self.read(node.operand, depth + 1)
            return -inner if isinstance(node.op, ast.USub) else inner
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            a, b = self.read(node.left, depth + 1), self.read(node.right, depth + 1)
            return _BINARY[type(node.op)](a, b)
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitXor):  # 2^10: Python's exclusive or
            self.refuse(f"'^' is not a power in an expression ({_short(_unparsed(node))}): write ** for a power, "
                        f"as in {_short(_unparsed(node).replace(' ^ ', '**'))}")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return self.power(self.read(node.left, depth + 1), self.read(node.right, depth + 1))
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "Piecewise":
            return self.piecewise(node, depth)
        if isinstance(node, ast.Call):
            func = node.func.id if isinstance(node.func, ast.Name) else None
            if func is None or func not in FUNCTIONS:
                shown = func or _unparsed(node.func)
                self.refuse(f"{shown!r} is not a function an expression may call (known: {_known()})")
            if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
                self.refuse(f"{func}() takes plain arguments only")
            args = [self.read(a, depth + 1) for a in node.args]
            if not args and func in ("max", "min", "Max", "Min"):  # SymPy's Max() is -oo (and cot(-oo) an interval)
                raise ExpressionError(f"{self.what}: {func}() takes one argument or more.")
            try:
                value = FUNCTIONS[func](*args)
            except (TypeError, ValueError) as exc:
                raise ExpressionError(f"{self.what}: {func}() cannot take these arguments ({exc}).") from None
            except (OverflowError, ZeroDivisionError, RecursionError):  # SymPy evaluates a number's function now:
                # erfc(1e308) overflows, cot(-cosh(1e308)) recurses in mpmath's argument reduction
                raise ExpressionError(f"{self.what}: {func}({', '.join(map(str, args))}) is not a finite number.") from None
            if _beyond_float(value):  # cosh(1e308), exp(10**30): a function of it would reduce 10**(4e29) digits
                raise ExpressionError(f"{self.what}: {func}({', '.join(map(str, args))}) is beyond a float's range.")
            return value
        self.refuse(f"{_short(_unparsed(node))} is not allowed")

    def piecewise(self, node: ast.Call, depth: int) -> sp.Expr:
        """``Piecewise((value, condition), ...)``: each argument a pair, the conditions read by :meth:`condition`."""
        pairs = node.args
        if node.keywords or not pairs or not all(isinstance(a, ast.Tuple) and len(a.elts) == 2 for a in pairs):
            self.refuse("Piecewise() takes pairs (value, condition), as Piecewise((0, t < 1), (1, True))")
        pieces = [(self.read(a.elts[0], depth + 2), self.condition(a.elts[1], depth + 2)) for a in pairs]
        try:
            return sp.Piecewise(*pieces)
        except (TypeError, ValueError) as exc:
            raise ExpressionError(f"{self.what}: Piecewise() cannot take these pieces ({exc}).") from None

    def condition(self, node: ast.AST, depth: int) -> sp.Basic:
        """A condition of ``Piecewise``: ``True``, ``False``, one comparison, or conditions joined by ``& | ~``."""
        if depth > MAX_DEPTH:
            raise ExpressionError(f"{self.what}: the expression nests deeper than {MAX_DEPTH} levels.")
        if isinstance(node, ast.Constant) and isinstance(node.value, bool):
            return sp.true if node.value else sp.false
        if isinstance(node, ast.Compare) and len(node.ops) == 1 and type(node.ops[0]) in _COMPARE:
            left, right = self.read(node.left, depth + 1), self.read(node.comparators[0], depth + 1)
            return _COMPARE[type(node.ops[0])](left, right)
        if isinstance(node, ast.BinOp) and type(node.op) in _LOGIC:
            return _LOGIC[type(node.op)](self.condition(node.left, depth + 1), self.condition(node.right, depth + 1))
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Invert):
            return sp.Not(self.condition(node.operand, depth + 1))
        self.refuse(f"{_short(_unparsed(node))} is not a condition (one comparison with < <= > >=, True, or "
                    f"conditions joined by & | ~)")

    def power(self, base: sp.Expr, exponent: sp.Expr) -> sp.Expr:
        """``base**exponent``; numbers only when the value fits a float (``9**9**9`` is refused, not computed)."""
        if base.is_number and exponent.is_number:
            small = exponent.is_Integer and abs(int(exponent)) <= 64 and base.is_Rational \
                and abs(base.p) < 2**64 and base.q < 2**64
            if not small:
                try:
                    value = math.pow(float(base), float(exponent))
                except (OverflowError, ValueError, TypeError):
                    value = math.inf
                if not math.isfinite(value):
                    raise ExpressionError(f"{self.what}: the power {base}**{exponent} is not a finite number.")
                if base.is_Rational and abs(base) != 1 and exponent.is_Rational and (abs(exponent.p) > 64 or exponent.q > 64):
                    # exactly, its numerator or denominator would have some |exponent| digits (3**-(10**31) underflows
                    # to 0.0, and SymPy would compute 3**(10**31) first): the float it fits
                    return sp.Float(value)
        return base**exponent
