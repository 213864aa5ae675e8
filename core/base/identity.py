"""Structural decisions about expressions: identically zero, equal, dependent on a symbol.

Whether a term vanishes identically, whether ``L`` depends explicitly on
time, whether momenta are linear in the velocities: these decide the
structure of a model (its first-order coordinates, its ignorable
coordinates, whether ``h`` is conserved, whether an effective potential
exists).  They are never decided by ``== 0`` on an expression with
floating-point numbers in it: ``0.3·0.7² − 0.147`` is a round-off residual,
not a term.  The rules here:

1. A structural zero (SymPy's own canonical form) is zero.  Nothing is
   expanded: expansion can blow up, and it merges terms whose
   floating-point coefficients differ by round-off into one tiny term that
   no longer shows its scale.
2. Otherwise the expression is evaluated at random points (several; every
   free symbol drawn log-uniformly over two decades, with the sign its
   assumptions allow, or set to its value where ``values`` gives one), in
   high precision (mpmath, 50 digits), along with its *magnitude*: the
   rounding it carries — the sum of its addends' magnitudes, for a product
   each factor's times the others' values, for a function its value plus
   its slope times its argument's (for a polynomial, about the evaluation
   with every addend's absolute value; for nested functions, growing with
   the depth rather than squaring at every level).  It is identically zero
   when the value is negligible against the magnitude at every point:
   below ``1e-11`` of it when floating-point numbers take part (their
   representation error is about ``1e-16``, amplified by the arithmetic
   that produced the expression), below ``1e-35`` when it is exact.
3. A point where the expression is not finite or not real (a singular set,
   the square root of a negative number off the physical domain) is
   replaced by another; when no point can be evaluated, SymPy's
   simplification decides, under a budget of operations.

A nonzero polynomial or elementary function vanishes on a set of measure
zero, so random points find it nonzero (Schwartz–Zippel); the points are
drawn from a fixed seed, so verdicts are reproducible.  The tolerance means
two terms that differ by less than ``1e-11`` of their size count as equal:
parameters spanning more than eleven decades *within one term* are beyond
it.

>>> import sympy as sp
>>> x, v = sp.symbols("x v", real=True)
>>> p, Mv = 0.3 * 0.7**2 * sp.sin(x)**2 * v, 0.147 * sp.sin(x)**2 * v
>>> p - Mv                                     # SymPy merges them: the scale is gone
-2.77555756156289e-17*v*sin(x)**2
>>> equal(p, Mv)
True
>>> is_zero(sp.sin(x)**2 + sp.cos(x)**2 - 1)
True
>>> equal(sp.sin(2 * x), 2 * sp.sin(x) * sp.cos(x)), equal(sp.sin(x), x)
(True, False)
>>> depends_on(sp.sin(x)**2 + sp.cos(x)**2 + v, x)
False
"""

from __future__ import annotations

import functools
import math
import random
import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any


from .budget import BudgetExceeded, interruptible
from . import deferred as _deferred

mpmath = _deferred.module("mpmath", globals())
sp = _deferred.module("sympy", globals())

__all__ = ["is_zero", "equal", "depends_on", "negligible", "nodes", "symbols_of", "FLOAT_TOLERANCE", "EXACT_TOLERANCE"]

#: Relative size below which a value counts as zero when floating-point numbers take part.
FLOAT_TOLERANCE = 1e-11
#: The same for exact expressions (integers, rationals, symbols), evaluated with 50 digits.
EXACT_TOLERANCE = 1e-35
_DIGITS = 50
_POINTS = 3
_TRIES = 12
_SEED = 20261124
_FAST_TOLERANCE = 1e-6  # a float evaluation this far from zero proves "not zero" at once
#: A floating-point expression whose double-precision value is below _FLOAT_ZERO of its magnitude (a normal number,
#: at least _FLOAT_NORMAL) at every point is zero without the 50-digit evaluation: the double evaluation errs by
#: about its depth × 1.1e-16 of the magnitude (one rounding per operation, each bounded by the magnitude as the
#: representation errors are), so its exact value is below FLOAT_TOLERANCE too for any expression less than
#: 90,000 operations deep.  Above it (and for exact expressions, whose tolerance is 1e-35) the 50-digit test decides.
_FLOAT_ZERO, _FLOAT_NORMAL = 1e-13, 1e-280
#: Beyond these arguments tanh is ±1 to within the tolerance of the test: 1 − tanh², its derivative, is about
#: 4·e^(−2x), below 1e-35 past 40 (exact expressions), below 1e-11 past 12 (floating-point ones) and below 1e-13
#: in double precision past 15.  Such a point cannot tell an expression in tanh from a constant, and is drawn again.
_SATURATED, _SATURATED_FLOATING, _SATURATED_FLOAT = 40.0, 11.5, 15.0


class _Inadmissible(Exception):
    """The expression has no finite real value at this point."""


class _FloatContext:
    """The slice of mpmath's context interface the evaluator uses, in double precision."""

    mpf = float
    fsum = staticmethod(math.fsum)
    isfinite = staticmethod(math.isfinite)
    atan2 = staticmethod(math.atan2)

    def __getattr__(self, name):
        return getattr(math, name)


_FLOAT = _FloatContext()


class _Evaluator:
    """Evaluate an expression and its magnitude (addends taken by absolute value) at one point."""

    def __init__(self, ctx, point: Mapping[Any, Any], saturated: float | None = None):
        self.ctx = ctx
        self.point = point
        self.saturated = saturated if saturated is not None else _SATURATED_FLOAT if ctx is _FLOAT else _SATURATED
        self.memo: dict = {}
        self.eps = 2.0**-52 if ctx is _FLOAT else ctx.eps  # (the working precision's unit)

    def __call__(self, e) -> tuple[Any, Any]:
        out = self.memo.get(e)
        if out is None:
            out = self._eval(e)
            self.memo[e] = out
        return out

    def _float(self, number):
        """A SymPy Float in this context's precision (its exact binary value in mpmath)."""
        if not number.is_Float:
            try:
                number = sp.Float(number, _DIGITS + 5)
            except (TypeError, ValueError):  # an unevaluated function of a number (DiracDelta(0)): no value
                raise _Inadmissible from None
        return float(number) if self.ctx is _FLOAT else self.ctx.mpf(number._mpf_)

    def _eval(self, e):
        ctx = self.ctx
        if e in self.point:
            x = self.point[e]
            return x, abs(x)
        if e.is_Rational:
            x = ctx.mpf(e.p) / e.q
            return x, abs(x)
        if e.is_Float:
            x = self._float(e)
            return x, abs(x)
        if e.is_NumberSymbol or e.is_number:
            x = e.evalf(_DIGITS + 5)
            if not x.is_real or not x.is_finite:
                raise _Inadmissible
            x = self._float(x)
            return x, abs(x)
        if e.is_Add:
            parts = [self(a) for a in e.args]
            return ctx.fsum(p[0] for p in parts), ctx.fsum(p[1] for p in parts)
        if e.is_Mul:
            # the magnitude of a product is the rounding it carries: each factor's times the others' values (relative
            # errors add), and their product at the working precision (the second-order term).  The product of the
            # magnitudes, an upper bound of the same for shallow expressions, squares at every level of a nested one
            # (sin(e)·cos(e) of a spatial chain's angles), past which every value looks negligible.
            parts = [self(a) for a in e.args]
            x = ctx.mpf(1)
            for xa, _ in parts:
                x *= xa
            m = ctx.mpf(0)
            for i, (_, mi) in enumerate(parts):
                term = mi
                for j, (xj, _) in enumerate(parts):
                    if j != i:
                        term *= abs(xj)
                m += term
            second = ctx.mpf(self.eps)
            for _, mi in parts:
                second *= mi
            return x, m + second
        if e.is_Pow:
            (xb, mb), (xe, _) = self(e.base), self(e.exp)
            if xb == 0 and xe < 0:
                raise _Inadmissible
            if xb < 0 and not e.exp.is_integer:
                raise _Inadmissible
            x = xb**xe
            if xb == 0:
                return x, mb**xe
            # an exponent multiplies the base's relative rounding error (mb / |xb|) by |exponent|
            return x, abs(x) * (1 + abs(xe) * mb / abs(xb))
        if isinstance(e, sp.Piecewise):
            for expr, cond in e.args:
                if self._truth(cond):
                    return self(expr)
            raise _Inadmissible  # no branch holds here
        if isinstance(e, (sp.Min, sp.Max)):
            parts = [self(a) for a in e.args]
            pick = min if isinstance(e, sp.Min) else max
            return pick(p[0] for p in parts), max(p[1] for p in parts)
        if isinstance(e, sp.Function) or isinstance(e, (sp.Abs, sp.sign)):
            return self._function(e)
        raise _Inadmissible

    def _truth(self, cond) -> bool:
        """The truth of a condition at this point (relations, and, or, not)."""
        if cond is sp.true or cond is True:
            return True
        if cond is sp.false or cond is False:
            return False
        if isinstance(cond, sp.And):
            return all(self._truth(c) for c in cond.args)
        if isinstance(cond, sp.Or):
            return any(self._truth(c) for c in cond.args)
        if isinstance(cond, sp.Not):
            return not self._truth(cond.args[0])
        if isinstance(cond, sp.core.relational.Relational):
            left, right = self(cond.lhs)[0], self(cond.rhs)[0]
            return bool({"<": left < right, "<=": left <= right, ">": left > right, ">=": left >= right,
                         "==": left == right, "!=": left != right}[cond.rel_op])
        raise _Inadmissible

    def _function(self, e):
        ctx = self.ctx
        args = [self(a) for a in e.args]
        name = _mp_names().get(type(e))
        if name is not None and len(args) == 1:
            xa, ma = args[0]
            if name == "tanh" and abs(xa) > self.saturated:
                # tanh is ±1 there to beyond the working precision, so 1 − tanh² (its derivative) would read 0: a
                # steep tanh (friction regularized over 1e-4 m/s) would look constant at every point
                raise _Inadmissible
            fn = getattr(ctx, name)
            try:
                x = fn(xa)
            except (ValueError, ZeroDivisionError, OverflowError):
                raise _Inadmissible from None
            if isinstance(x, (complex, mpmath.mpc)):
                raise _Inadmissible
            slope = _SLOPES[name](x, xa)
            return x, abs(x) + slope * ma
        if isinstance(e, sp.Abs):
            return abs(args[0][0]), args[0][1]
        if isinstance(e, sp.sign):
            xa, ma = args[0]
            one = ctx.mpf(1)
            return (one if xa > 0 else -one if xa < 0 else 0 * one), one
        if isinstance(e, sp.atan2):
            (y, my), (x, mx) = args
            val = ctx.atan2(y, x)
            return val, abs(val) + my + mx
        if isinstance(e, (sp.floor, sp.ceiling)):
            val = (ctx.floor if isinstance(e, sp.floor) else ctx.ceil)(args[0][0])
            return ctx.mpf(val), abs(ctx.mpf(val)) + args[0][1]
        if isinstance(e, sp.Heaviside):
            xa = args[0][0]
            one = ctx.mpf(1)
            val = one if xa > 0 else 0 * one if xa < 0 else (args[1][0] if len(args) > 1 else one / 2)
            return val, one
        if isinstance(e, sp.Mod):
            (a, ma), (b, mb) = args
            val = a - b * ctx.floor(a / b)
            return val, abs(val) + ma + mb
        # anything else: SymPy evaluates it at the point, its magnitude taken as its size plus its arguments'
        subs = [sp.Float(a[0], _DIGITS) for a in args]
        value = e.func(*subs).evalf(_DIGITS)
        if not value.is_number or not value.is_real or not value.is_finite:
            raise _Inadmissible
        x = self._float(value)
        return x, abs(x) + sum(a[1] for a in args)


@functools.cache
def _mp_names() -> dict:
    """SymPy's functions that mpmath evaluates, to mpmath's names of them."""
    return {getattr(sp, name): name for name in ("sin", "cos", "tan", "exp", "log", "asin", "acos", "atan", "sinh",
                                                 "cosh", "tanh")}


_SLOPES: dict[str, Callable] = {  # |f'| at the point, to carry the argument's rounding through
    "sin": lambda x, a: 1, "cos": lambda x, a: 1, "tan": lambda x, a: 1 + x * x,
    "exp": lambda x, a: abs(x), "log": lambda x, a: 1 / abs(a) if a else 0,
    "asin": lambda x, a: 1 / math.sqrt(max(1e-300, 1 - float(a) ** 2)),
    "acos": lambda x, a: 1 / math.sqrt(max(1e-300, 1 - float(a) ** 2)),
    "atan": lambda x, a: 1, "sinh": lambda x, a: abs(x) + 1, "cosh": lambda x, a: abs(x) + 1,
    "tanh": lambda x, a: 1,
}


def nodes(exprs: Iterable, seen: set | None = None) -> set:
    """Every distinct sub-expression of ``exprs`` (expressions or matrices), each visited once.

    SymPy's ``atoms`` and ``free_symbols`` visit a shared sub-expression once per occurrence: exponential in the
    nesting depth for expressions such as a spatial chain's, where each body's velocity is nested in every body's
    beyond it (16.5 million visits for the equations of four bodies on spherical joints, against 3,267 here).
    Nodes that bind symbols (an integral's variable) are kept whole and not entered.  ``seen``: nodes visited before
    (by an earlier call), neither entered nor returned; the new ones are added to it."""
    found: set = set()
    before = seen if seen is not None else set()
    stack = [e for x in exprs for e in (entries(x) if isinstance(x, sp.MatrixBase) else (x,))]
    while stack:
        e = stack.pop()
        if e in found or e in before:
            continue
        found.add(e)
        if e.args and not getattr(e, "bound_symbols", None):
            stack.extend(e.args)
    if seen is not None:
        seen |= found
    return found


def entries(matrix: sp.MatrixBase) -> list:
    """The distinct entries of ``matrix``: its nonzero ones, and zero when it has a zero entry — read from its
    sparse store, so that a diagonal matrix of 10⁴ rows costs 10⁴ steps, not 10⁸ (indexing a SymPy matrix entry
    by entry costs microseconds each).

    >>> x = sp.Symbol("x")
    >>> sorted(entries(sp.diag(x, 2 * x, x)), key=str)
    [0, 2*x, x]
    """
    found = matrix.todok()
    out = list(set(found.values()))
    if len(found) < matrix.rows * matrix.cols:
        out.append(sp.S.Zero)
    return out


def symbols_of(exprs: Iterable) -> set:
    """The free symbols of ``exprs``, visiting each distinct sub-expression once (:func:`nodes`; SymPy's
    ``free_symbols`` walks a shared one once per occurrence)."""
    out: set = set()
    for e in nodes(exprs):
        if e.is_Symbol:
            out.add(e)
        elif e.args and getattr(e, "bound_symbols", None):
            out |= e.free_symbols
    return out


def _has_float(expr, values: Mapping, found: set | None = None) -> bool:
    found = nodes([expr]) if found is None else found
    return any(e.is_Float for e in found) or any(isinstance(v, float) or getattr(v, "is_Float", False)
                                                 for v in values.values())


def _opaque(expr, found: set | None = None) -> list:
    """Sub-expressions treated as independent unknowns: free symbols, applied undefined functions, derivatives
    (each distinct sub-expression visited once: :func:`nodes`)."""
    out: set = set()
    for e in nodes([expr]) if found is None else found:
        if e.is_Symbol or isinstance(e, (sp.core.function.AppliedUndef, sp.Derivative)):
            out.add(e)
        elif e.args and getattr(e, "bound_symbols", None):
            out |= e.free_symbols
    return sorted(out, key=sp.default_sort_key)


def _draw(rng: random.Random, s) -> float:
    """A generic value for ``s``, of the sign its assumptions allow."""
    if getattr(s, "is_integer", None):
        value = float(rng.randint(2, 9))
    else:
        value = 10 ** rng.uniform(-1, 1) * (1 + 1e-3 * rng.random())
    if getattr(s, "is_nonpositive", None):
        return -value
    if getattr(s, "is_nonnegative", None) or getattr(s, "is_positive", None):
        return value
    return value if rng.random() < 0.5 else -value


def _points(expr, values: Mapping, seed: int, found: set | None = None):
    rng = random.Random(seed)
    unknowns = [s for s in _opaque(expr, found) if s not in values]
    while True:
        yield {**values, **{s: _draw(rng, s) for s in unknowns}}


def negligible(value, magnitude, floating: bool) -> bool:
    """Whether ``value`` is zero relative to ``magnitude`` (the size of the terms it came from)."""
    tol = FLOAT_TOLERANCE if floating else EXACT_TOLERANCE
    return abs(value) <= tol * abs(magnitude)


def is_zero(expr, values: Mapping[Any, Any] | None = None, *, points: int = _POINTS) -> bool:
    """Whether ``expr`` is identically zero (for every value of its free symbols, except those in ``values``).

    ``values`` fixes some symbols (parameters with values); the others are
    drawn at random.  See the module's docstring for the rules.

    >>> import sympy as sp
    >>> x = sp.Symbol("x", real=True)
    >>> is_zero(sp.cos(x)**2 - (1 + sp.cos(2 * x)) / 2), is_zero(x - sp.sin(x))
    (True, False)
    >>> k = sp.Symbol("k", positive=True)
    >>> is_zero((k - 2) * x, {k: 2}), is_zero((k - 2) * x)
    (True, False)
    """
    expr = sp.sympify(expr)
    if isinstance(expr, sp.MatrixBase):
        return all(is_zero(e, values, points=points) for e in expr)
    if expr == 0:
        return True
    found = nodes([expr])  # (SymPy's is_number and free_symbols walk a shared sub-expression once per occurrence)
    if not _opaque(expr, found):
        value = expr.evalf(_DIGITS)
        if value.is_real and value.is_finite:
            return bool(value == 0)
        return False
    # the values of the symbols the expression holds, looked up from them: every value of a model of 10⁴
    # parameters, for each of its 10⁴ mass-matrix entries, took 20 of 28 s for 1,000 masses
    given = values or {}
    return _zero_at_points(expr, {k: sp.sympify(given[k]) for k in found if k in given}, points, found)


@functools.cache
def _piecewise() -> tuple:
    return sp.Piecewise, sp.Heaviside, sp.Min, sp.Max


def _zero_by_branches(expr, values: Mapping, points: int) -> bool:
    """A piecewise expression vanishes on whole intervals, where random points may all fall: it is decided
    branch by branch (zero when every branch is), never by points alone.  Folding the branches together can
    multiply them, so it runs under a budget, past which the expression counts as not zero."""
    try:
        folded = interruptible(lambda: sp.piecewise_fold(expr.rewrite(sp.Piecewise)), seconds=SYMBOLIC_SECONDS)
    except BudgetExceeded:
        return False
    if isinstance(folded, sp.Piecewise):
        return all(is_zero(branch, values, points=points) for branch, _ in folded.args)
    if folded.has(*_piecewise()):  # nested where folding could not reach: not decided, so not zero
        return False
    return is_zero(folded, values, points=points)


def _zero_at_points(expr, values: Mapping, points: int, found: set | None = None) -> bool:
    if found is None:  # (walked once, each shared sub-expression once: atoms and has walk every occurrence)
        found = nodes([expr])
    if any(isinstance(e, _piecewise()) for e in found):
        return _zero_by_branches(expr, values, points)
    floating = _has_float(expr, values, found)
    gen = _points(expr, values, _SEED, found)
    # fast path in double precision: one evaluation far from zero proves it is not identically zero; a floating-point
    # expression far below its tolerance at every point is zero (below)
    tested = 0
    for _ in range(_TRIES + points):
        point = next(gen)
        try:
            x, m = _Evaluator(_FLOAT, {k: float(v) for k, v in point.items()},
                              _SATURATED_FLOATING if floating else None)(expr)
        except (_Inadmissible, TypeError, ValueError, OverflowError, ZeroDivisionError):
            continue
        if not (math.isfinite(x) and math.isfinite(m)):
            break
        if abs(x) > _FAST_TOLERANCE * m:
            return False
        if not (floating and m >= _FLOAT_NORMAL and abs(x) <= _FLOAT_ZERO * m):
            break
        tested += 1
        if tested >= points:
            return True
    ctx = _context()
    tested = 0
    for _ in range(_TRIES + points):
        point = next(gen)
        try:
            x, m = _Evaluator(ctx, {k: _mp(ctx, v) for k, v in point.items()},
                              _SATURATED_FLOATING if floating else _SATURATED)(expr)
        except (_Inadmissible, TypeError, ValueError, OverflowError, ZeroDivisionError):
            continue
        if not (ctx.isfinite(x) and ctx.isfinite(m)):
            continue
        if not negligible(x, m, floating):
            return False
        tested += 1
        if tested >= points:
            return True
    return _symbolic_zero(expr)


def _mp(ctx, v):
    if isinstance(v, float):
        return ctx.mpf(v)
    v = sp.sympify(v)
    if v.is_Rational:
        return ctx.mpf(v.p) / v.q
    if v.is_Float:
        return ctx.mpf(v._mpf_)
    value = v.evalf(_DIGITS + 5)
    if not value.is_real:
        raise _Inadmissible
    return ctx.mpf(value._mpf_)


#: Seconds the last resort (SymPy's ``simplify``) may take before the expression counts as not zero.
SYMBOLIC_SECONDS = 2.0


def _symbolic_zero(expr, limit: int = 200) -> bool:
    """Last resort where no point evaluates: SymPy's simplification, for expressions small enough and under
    a budget (past which the expression is not known to be zero: not zero)."""
    if sp.count_ops(expr) > limit:
        return False
    try:
        return interruptible(lambda: sp.simplify(expr) == 0, seconds=SYMBOLIC_SECONDS)
    except BudgetExceeded:
        return False
    except Exception:  # pragma: no cover - SymPy corner cases
        return False


def equal(a, b, values: Mapping[Any, Any] | None = None, *, points: int = _POINTS) -> bool:
    """Whether ``a`` and ``b`` are identically equal, compared term by term at random points.

    ``a`` and ``b`` are evaluated separately and compared against the sum of
    both magnitudes, so a round-off difference between floating-point
    coefficients is never mistaken for a term (SymPy would merge
    ``0.147·x − 0.14699999999999999·x`` into ``2.8e-17·x`` and lose its scale).

    >>> import sympy as sp
    >>> x = sp.Symbol("x", real=True)
    >>> equal(0.3 * 0.49 * sp.sin(x), 0.147 * sp.sin(x)), equal(0.3 * sp.sin(x), 0.30001 * sp.sin(x))
    (True, False)
    """
    a, b = sp.sympify(a), sp.sympify(b)
    if isinstance(a, sp.MatrixBase) or isinstance(b, sp.MatrixBase):
        a, b = sp.Matrix(a), sp.Matrix(b)
        return a.shape == b.shape and all(equal(x, y, values, points=points) for x, y in zip(a, b))
    if a == b:
        return True
    pair = sp.Tuple(a, b)
    given = values or {}
    found = nodes([pair])
    values = {k: sp.sympify(given[k]) for k in found if k in given}  # (the values of its symbols alone)
    # the difference, kept unevaluated so its addends are a's and b's own
    diff = sp.Add(a, sp.Mul(-1, b, evaluate=False), evaluate=False)
    if not _opaque(pair, found):
        try:
            x, m = _Evaluator(_context(), {})(diff)
        except _Inadmissible:
            return False
        return negligible(x, m, _has_float(pair, values))
    return _zero_at_points(diff, values, points)


_CONTEXTS = threading.local()


def _context():
    """This thread's mpmath context at :data:`_DIGITS` digits: made once per thread (a new one costs 0.2 ms, as
    much as the evaluations it serves), one per thread as a context's precision is its own state."""
    ctx = getattr(_CONTEXTS, "ctx", None)
    if ctx is None:
        ctx = _CONTEXTS.ctx = mpmath.MPContext()
    ctx.dps = _DIGITS
    return ctx


def depends_on(expr, symbol, values: Mapping[Any, Any] | None = None, *, diff: Callable | None = None) -> bool:
    """Whether ``expr`` really depends on ``symbol``: its derivative is not identically zero.

    ``diff(expr, symbol)`` differentiates (SymPy's by default; a memoized
    one from :class:`lagrangian.derive.Calculus` for large expressions).

    >>> import sympy as sp
    >>> t, w = sp.symbols("t omega", real=True)
    >>> depends_on(0.3 * sp.sin(w * t)**2 + 0.3 * sp.cos(w * t)**2, t), depends_on(sp.sin(w * t), t)
    (False, True)
    """
    expr = sp.sympify(expr)
    if symbol not in (symbols_of([expr]) if symbol.is_Symbol else nodes([expr])):  # (each shared part once)
        return False
    derivative = (diff or sp.diff)(expr, symbol)
    return not is_zero(derivative, values)
