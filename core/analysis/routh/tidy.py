"""Cosmetic simplification of the expressions of a reduction, under a time budget.

:func:`_tidy` simplifies small expressions (floats kept as they are) and gives
up after :data:`TIDY_SECONDS`; :func:`_terms` writes a result as a sum of tidied
terms; :func:`_drop` puts a constant in for symbols an expression does not
really depend on; :func:`_factors_vanishing` lists the factors of a determinant
that can be zero (the singularities of a reduction).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence

from ...base.budget import BudgetExceeded, interruptible
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: Seconds one cosmetic simplification may take before the expression is kept as it is.
TIDY_SECONDS = 2.0


def _tidy(expr: sp.Expr, limit: int = 100) -> sp.Expr:
    """A cheap simplification, skipped for large expressions (floats are kept as they are, not spread).

    Cosmetic: ``cancel(together(...))``, then ``sin² + cos² = 1`` where it
    shortens (:func:`_squares_to_one`), under a budget of :data:`TIDY_SECONDS`
    (cancelling can take minutes on some coefficients), past which the
    expression stays as it is — equally exact.  Remembered per expression (:data:`TIDY_CACHE` of the
    most recent): a reduction tidies the same entries again and again (the
    matrix, its adjugate, the rates), and so do reductions of one structure."""
    expr = sp.sympify(expr)
    if expr.count_ops() > limit:
        return expr
    return _tidied(expr)


#: How many tidied expressions :func:`_tidy` remembers (least recently used dropped first).
TIDY_CACHE = 4096


@functools.lru_cache(maxsize=TIDY_CACHE)
def _tidied(expr: sp.Expr) -> sp.Expr:
    try:
        return interruptible(_simplified, expr, seconds=TIDY_SECONDS)
    except BudgetExceeded:
        return expr


def _simplified(expr: sp.Expr) -> sp.Expr:
    floats = {f: sp.Dummy() for f in expr.atoms(sp.Float)}
    try:
        out = sp.cancel(sp.together(expr.xreplace(floats)))
        # the identities pay off on small expressions with trigonometric functions, and cost seconds on large ones
        if sp.count_ops(out) <= 80 and out.has(sp.functions.elementary.trigonometric.TrigonometricFunction, sp.functions.elementary.hyperbolic.HyperbolicFunction):
            out = _squares_to_one(out)
    except (sp.PolynomialError, TypeError, ValueError):  # pragma: no cover - sympy corner cases
        return expr
    out = out.xreplace({d: f for f, d in floats.items()})
    return out if sp.count_ops(out) <= sp.count_ops(expr) else expr


def _squares_to_one(expr: sp.Expr) -> sp.Expr:
    """``expr`` with ``sin²`` written ``1 − cos²`` or the other way round, for each angle, whichever is shortest
    (and ``cosh² − sinh² = 1`` likewise).

    In place of SymPy's ``trigsimp``, which the tidy called before: the identity is what the reductions' entries
    need (sin² + cos² gone before the solve spreads it), and on the reductions of ``tests/test_decisions.py``
    this takes 19 ms a call where ``trigsimp`` took 243 ms (cProfile, 43 and 45 calls), with the same verdicts."""
    best, ops = expr, sp.count_ops(expr)
    def angles(*kinds):
        return sorted({f.args[0] for f in expr.atoms(*kinds)}, key=sp.default_sort_key)  # the same order every run

    pairs = [(sp.sin(a), sp.cos(a), 1) for a in angles(sp.sin, sp.cos)]
    pairs += [(sp.sinh(a), sp.cosh(a), -1) for a in angles(sp.sinh, sp.cosh)]
    for s, c, sign in pairs:
        for old, new in ((s**2, sign * (1 - c**2)), (c**2, 1 - sign * s**2)):
            if not best.has(old):
                continue
            candidate = sp.cancel(best.subs(old, new))
            n = sp.count_ops(candidate)
            if n < ops:
                best, ops = candidate, n
    return best


def _terms(expr: sp.Expr, limit: int = 100) -> sp.Expr:
    """A sum of simple terms (how R, V_eff and T read best), each tidied; large expressions as they are."""
    expr = _tidy(expr, limit)
    if expr.count_ops() > limit:
        return expr
    return sp.Add(*[_tidy(term, limit) for term in sp.Add.make_args(sp.expand(expr))])


def _drop(expr: sp.Expr, symbols: Sequence[sp.Symbol]) -> sp.Expr:
    """``expr`` with symbols it does not depend on replaced by a constant (0, or a generic value if 0 is singular)."""
    for value in (sp.Integer(0), sp.Rational(1, 3)):
        out = sp.sympify(expr).xreplace({s: value for s in symbols})
        if not out.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
            return out
    return expr  # pragma: no cover - singular at both values


def _factors_vanishing(det: sp.Expr) -> list[sp.Expr]:
    """Factors of ``det`` that can vanish (not numbers, not always-positive)."""
    out = []
    try:
        factored = interruptible(sp.factor, det, seconds=TIDY_SECONDS)
    except BudgetExceeded:
        factored = det
    for f in sp.Mul.make_args(factored):
        base = f.base if isinstance(f, sp.Pow) and f.exp.is_positive else f
        if base.is_number or (isinstance(f, sp.Pow) and f.exp.is_negative):
            continue
        if base.is_positive:
            continue
        if base not in out:
            out.append(base)
    return out
