"""Cosmetic simplification of the expressions of a reduction, under a time budget.

:func:`_tidy` simplifies small expressions (floats kept as they are) and gives
up after :data:`TIDY_SECONDS`; :func:`_terms` writes a result as a sum of tidied
terms; :func:`_drop` puts a constant in for symbols an expression does not
really depend on; :func:`_factors_vanishing` lists the factors of a determinant
that can be zero (the singularities of a reduction).
"""

from __future__ import annotations

from collections.abc import Sequence

import sympy as sp

from ...base.budget import BudgetExceeded, interruptible


#: Seconds one cosmetic simplification may take before the expression is kept as it is.
TIDY_SECONDS = 2.0


def _tidy(expr: sp.Expr, limit: int = 100) -> sp.Expr:
    """A cheap simplification, skipped for large expressions (floats are kept as they are, not spread).

    Cosmetic: under a budget of :data:`TIDY_SECONDS` (``trigsimp`` can factor
    for minutes on some coefficients), past which the expression stays as it
    is — equally exact."""
    expr = sp.sympify(expr)
    if expr.count_ops() > limit:
        return expr
    try:
        return interruptible(_simplified, expr, seconds=TIDY_SECONDS)
    except BudgetExceeded:
        return expr


def _simplified(expr: sp.Expr) -> sp.Expr:
    floats = {f: sp.Dummy() for f in expr.atoms(sp.Float)}
    try:
        out = sp.cancel(sp.together(expr.xreplace(floats)))
        if sp.count_ops(out) <= 80:  # trigsimp pays off on small expressions and costs seconds on large ones
            out = sp.trigsimp(out)
    except (sp.PolynomialError, TypeError, ValueError):  # pragma: no cover - sympy corner cases
        return expr
    out = out.xreplace({d: f for f, d in floats.items()})
    return out if sp.count_ops(out) <= sp.count_ops(expr) else expr


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
