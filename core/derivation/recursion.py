"""Recursive dynamics a domain offers (:class:`~lagrangian.RecursiveDynamics`), taken in place of closed-form
equations when the rest of the model lets it: see :func:`take`.

The recursion computes the accelerations from the coordinates, their rates and the generalized forces ``τ`` of
every component it does not cover, which store no kinetic energy: ``τ = Q − ∂V/∂q − ∂D/∂q̇`` over those components
(springs, dampers, loads), derived from their energies as usual.  The closed-form equations of the same model are
still there, derived when something asks for them (display, linearization, the Routhian).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..base.domain import Recursion, RecursiveDynamics
from ..errors import ModelError

#: A pivot of the recursion at most this fraction of the largest, at a random state, is zero: the motion of that
#: coordinate is not determined by the recursion (a massless end of a chain), and the closed form decides.
PIVOT_FLOOR = 1e-9


@dataclass
class Taken:
    """The recursion a model's equations use: the :class:`~lagrangian.Recursion`, in the equations' plain symbols
    (its ``accelerations`` in the order of the equations' coordinates), and a note for reports."""

    recursion: Recursion
    note: str


def _offer(assembly) -> RecursiveDynamics | None:
    offers = [v.recursive for v in assembly.generic_views.values() if getattr(v, "recursive", None) is not None]
    return offers[0] if offers else None


def _why_not(assembly, offer: RecursiveDynamics, names: list[str]) -> str | None:
    """Why the rest of the model keeps the recursion from serving it, or None."""
    others = [n for n in names if n not in set(offer.names)]
    if others:
        return f"coordinates {', '.join(others)} are not coordinates of the joints"
    if assembly.eliminated:
        return f"constraints eliminate {', '.join(assembly.eliminated)}"
    for name, c in assembly.generic.items():
        if name in offer.covers:
            continue
        for part, what in (("T", "stores kinetic energy"), ("G", "adds a velocity-linear coupling")):
            if sp.sympify(getattr(c, part)) != 0:
                return f"component {name!r} {what}"
        if c.frames:
            return f"component {name!r} moves a frame of its own"
        if c.constraints or c.velocity_constraints:
            return f"component {name!r} adds constraints"
    return None


def take(assembly, eq, Q: list[sp.Expr], calc) -> Taken | None:
    """The recursion ``eq`` (an :class:`~lagrangian.derivation.equations.Equations` being built) uses, or None for
    the closed-form equations: when a domain offers one, every coordinate is one of its own, every component it
    does not cover stores no kinetic energy and adds no constraint, and every pivot is positive at a random state.
    ``Q``: the generalized forces of the loads, in ``eq``'s plain symbols; ``calc``: the derivation's differentiator.  A recursion the user asked for that
    cannot serve is refused by name."""
    offer = _offer(assembly)
    if offer is None:
        return None
    why = _why_not(assembly, offer, eq.names)
    if why is not None:
        if offer.forced:
            raise ModelError(f"dynamics='recursive' cannot serve this model: {why}. Use dynamics='closed' (or 'auto').")
        return None
    q, v = eq.sym.q, eq.sym.v
    rest = [c for name, c in assembly.generic.items() if name not in offer.covers]
    V = eq.symbolic(sp.Add(*(sp.sympify(c.V) for c in rest)))
    D = eq.symbolic(sp.Add(*(sp.sympify(c.D) for c in rest)))
    tau = [Q[i] - calc.diff(V, q[i]) - calc.diff(D, v[i]) for i in range(len(q))]
    by_name = dict(zip(eq.names, range(len(q))))
    order = [by_name[n] for n in offer.names]
    rec = offer.build([q[i] for i in order], [v[i] for i in order], [tau[i] for i in order])
    place = {i: k for k, i in enumerate(order)}  # the model's coordinate i is the recursion's place[i]
    rec = Recursion(rec.definitions, [rec.accelerations[place[i]] for i in range(len(q))], rec.kinetic,
                    [rec.momenta[place[i]] for i in range(len(q))], [rec.pivots[place[i]] for i in range(len(q))])
    bad = _zero_pivots(rec, eq)
    if bad:
        if offer.forced:
            raise ModelError(f"dynamics='recursive': coordinate(s) {', '.join(bad)} have no inertia about their "
                             f"joints' axes (nothing massive beyond them), so the articulated-body algorithm cannot "
                             f"give their accelerations. Use dynamics='closed' (or 'auto'), which treats them as "
                             f"first-order coordinates when they are damped.")
        return None
    return Taken(rec, offer.note)


def _zero_pivots(rec: Recursion, eq) -> list[str]:
    """The coordinates whose pivots are zero (or not finite) at a random state, parameters without values drawn at
    random within a decade of 1 (a model given symbols decides as its twin given numbers)."""
    q, v = eq.sym.q, eq.sym.v
    rng = np.random.default_rng(11)
    env: dict = {s: float(x) for s, x in eq._values.items()}
    env |= dict(zip(q, rng.uniform(-0.7, 0.7, len(q)))) | dict(zip(v, rng.uniform(-0.7, 0.7, len(v))))
    try:
        with np.errstate(all="ignore"):
            for s, e in rec.definitions:
                env[s] = _value(e, env, rng)
            out = np.array([_value(p, env, rng) for p in rec.pivots], dtype=float)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return list(eq.names)
    finite = np.isfinite(out)
    top = float(np.max(np.abs(out[finite]))) if finite.any() else 0.0
    zero = [eq.names[i] for i in range(len(out)) if finite[i] and not out[i] > PIVOT_FLOOR * top]
    # (a zero pivot makes every pivot nearer the ground not finite: the zero ones are the cause)
    return zero or [eq.names[i] for i in range(len(out)) if not finite[i]]


_RELATIONS = {sp.StrictGreaterThan: lambda a, b: a > b, sp.GreaterThan: lambda a, b: a >= b,
              sp.StrictLessThan: lambda a, b: a < b, sp.LessThan: lambda a, b: a <= b}
_UNARY = {sp.sin: np.sin, sp.cos: np.cos, sp.tan: np.tan, sp.exp: np.exp, sp.log: np.log, sp.sqrt: np.sqrt,
          sp.Abs: np.abs}


def _value(e: sp.Expr, env: dict, rng) -> float:
    """``e`` in floats, its symbols from ``env`` (a symbol without a value gets one drawn within a decade of 1)."""
    if e.is_Number:
        return float(e)
    if e.is_Symbol:
        if e not in env:
            env[e] = float(10 ** rng.uniform(-0.5, 0.5))
        return env[e]
    if isinstance(e, sp.Piecewise):  # (a recursion's guarded division: NaN where no branch holds)
        for expr, cond in e.args:
            compare = _RELATIONS.get(type(cond))
            if cond is sp.true or (compare is not None and compare(_value(cond.lhs, env, rng), _value(cond.rhs, env, rng))):
                return _value(expr, env, rng)
        return float("nan")
    args = [_value(a, env, rng) for a in e.args]
    if e.is_Add:
        return float(np.sum(args))
    if e.is_Mul:
        return float(np.prod(args))
    if e.is_Pow:
        return float(np.float64(args[0]) ** args[1])
    if e.func in _UNARY:
        return float(_UNARY[e.func](args[0]))
    return float(e.xreplace({a: sp.Float(x) for a, x in zip(e.args, args)}))
