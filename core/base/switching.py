"""Where functions of time switch branch: the corners of pulses, steps and square waves.

A model's inputs are often piecewise in ``t`` (``Piecewise``, ``Heaviside``,
``sign``, ``Abs``, ``Min``/``Max``, ``floor``, ``ceiling``, ``frac``,
``Mod``: a SPICE PULSE is a trapezoid in ``Mod(t − td, per)``).  The exact
solution of a linear model (:mod:`lagrangian.linear`) solves each piece on
its own, and adaptive integrators (:func:`lagrangian.integrate.integrate`)
restart at each switch, so that no step straddles a corner: an error
estimate taken across a kink can be small by chance, and a step that
straddles one can then be wrong by 1e-6 at ``rtol=1e-11``.

>>> import sympy as sp
>>> from lagrangian import t
>>> pulse = sp.Piecewise((0, t < 1), (1, sp.Mod(t - 1, 2) < 0.5), (0, True))
>>> switching_times([pulse], 0.0, 4.0)
[1.0, 1.5, 3.0, 3.5]
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from .component import t
from . import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: at most this many switches in one span
MAX_PIECES = 200_000


@functools.cache
def switches() -> tuple:
    """The functions that switch branch (SymPy's: imported on first call)."""
    return sp.Piecewise, sp.Heaviside, sp.sign, sp.Abs, sp.Min, sp.Max, sp.floor, sp.ceiling, sp.frac, sp.Mod


def switching_times(exprs: Sequence[sp.Expr], lo: float, hi: float) -> list[float]:
    """Times in ``(lo, hi)`` where some switching function of ``exprs`` may change branch; raises ``ValueError``."""
    found: set[float] = set()
    for expr in exprs:
        for atom in expr.atoms(*switches()):
            if t not in atom.free_symbols:
                continue
            if isinstance(atom, sp.Piecewise):
                for _, cond in atom.args:
                    for rel in getattr(cond, "atoms", lambda *_: ())(sp.core.relational.Relational):
                        found.update(_crossings(rel.lhs - rel.rhs, None, lo, hi, rel))
            elif isinstance(atom, (sp.Heaviside, sp.sign, sp.Abs)):
                found.update(_crossings(atom.args[0], None, lo, hi, atom))
            elif isinstance(atom, (sp.Min, sp.Max)):
                args = atom.args
                for i in range(len(args)):
                    for j in range(i + 1, len(args)):
                        found.update(_crossings(args[i] - args[j], None, lo, hi, atom))
            elif isinstance(atom, sp.Mod):
                p, q = atom.args
                if t in q.free_symbols:
                    raise ValueError(f"{atom}: the modulus depends on t")
                found.update(_crossings(p, float(q), lo, hi, atom))
            else:  # floor, ceiling, frac
                found.update(_crossings(atom.args[0], 1.0, lo, hi, atom))
            if len(found) > MAX_PIECES:
                raise ValueError(f"{atom} switches more than {MAX_PIECES} times in [{lo:g}, {hi:g}]")
    return sorted(found)


def _crossings(fun: sp.Expr, step: float | None, lo: float, hi: float, atom) -> list[float]:
    """Times in ``(lo, hi)`` where ``fun`` crosses zero (``step`` None) or a multiple of ``step``.

    A ``fun`` that itself switches (``Mod(t, P) < w``) is split at its own switching times first.
    """
    find = _zeros if step is None else (lambda f, a, b, at: _levels(f, step, a, b, at))
    if not fun.has(*switches()):
        return find(fun, lo, hi, atom)
    inner = switching_times([fun], lo, hi)
    edges = [lo, *inner, hi]
    out = list(inner)
    for a, b in zip(edges[:-1], edges[1:]):
        if b > a:
            out += find(resolve(fun, (a + b) / 2), a, b, atom)
    return out


def _zeros(expr: sp.Expr, lo: float, hi: float, atom) -> list[float]:
    """Real zeros of ``expr`` (a function of t) in ``(lo, hi)``, found symbolically."""
    expr = sp.expand(expr)
    if t not in expr.free_symbols:
        return []
    if expr.is_polynomial(t):
        coeffs = [complex(sp.N(c)) for c in sp.Poly(expr, t).all_coeffs()]
        if len(coeffs) == 2:
            roots = [-coeffs[1].real / coeffs[0].real]
        else:
            roots = [r.real for r in np.roots(coeffs) if abs(r.imag) <= 1e-12 * max(1.0, abs(r))]
    else:
        try:
            sol = sp.solveset(expr, t, sp.Interval(lo, hi))
        except Exception:  # noqa: BLE001 - SymPy may fail in many ways; we only need a yes or no
            sol = None
        if not isinstance(sol, sp.FiniteSet):
            raise ValueError(f"cannot find symbolically where {atom} switches")
        roots = [float(sp.N(r)) for r in sol]
    return [r for r in roots if lo < r < hi]


def _levels(expr: sp.Expr, step: float, lo: float, hi: float, atom) -> list[float]:
    """Times in ``(lo, hi)`` where the linear ``expr`` crosses a multiple of ``step``."""
    expr = sp.expand(expr)
    if not expr.is_polynomial(t) or sp.degree(expr, t) > 1:
        raise ValueError(f"{atom}: only an argument linear in t is supported")
    slope, offset = float(expr.coeff(t, 1)), float(expr.coeff(t, 0))
    if slope == 0:
        return []
    a, b = sorted(((slope * lo + offset) / step, (slope * hi + offset) / step))
    first, last = math.floor(a) + 1, math.ceil(b) - 1
    if last - first > MAX_PIECES:
        raise ValueError(f"{atom} switches more than {MAX_PIECES} times in [{lo:g}, {hi:g}]")
    return [(k * step - offset) / slope for k in range(first, last + 1)]


def resolve(expr: sp.Expr, at: float) -> sp.Expr:
    """``expr`` with every switching function replaced by the branch it takes at time ``at``."""
    if not expr.has(*switches()):
        return expr
    if isinstance(expr, sp.Piecewise):
        for branch, cond in expr.args:
            if bool(cond.subs(t, at)) is True:
                return resolve(branch, at)
        raise ValueError(f"{expr} is undefined at t = {at:g}")
    if not expr.args:
        return expr
    args = [resolve(a, at) for a in expr.args]

    def value(e) -> float:
        return float(sp.N(e.xreplace({t: sp.Float(at)})))

    if isinstance(expr, sp.Heaviside):
        return sp.Integer(1 if value(args[0]) > 0 else 0)
    if isinstance(expr, sp.sign):
        return sp.Integer(int(np.sign(value(args[0]))))
    if isinstance(expr, sp.Abs):
        return args[0] if value(args[0]) >= 0 else -args[0]
    if isinstance(expr, (sp.Min, sp.Max)):
        vals = [value(a) for a in args]
        pick = int(np.argmin(vals) if isinstance(expr, sp.Min) else np.argmax(vals))
        return args[pick]
    if isinstance(expr, sp.floor):
        return sp.Integer(math.floor(value(args[0])))
    if isinstance(expr, sp.ceiling):
        return sp.Integer(math.ceil(value(args[0])))
    if isinstance(expr, sp.frac):
        return args[0] - math.floor(value(args[0]))
    if isinstance(expr, sp.Mod):
        p, q = args
        return p - q * math.floor(value(p) / value(q))
    return expr.func(*args)
