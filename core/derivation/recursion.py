"""Recursive dynamics a domain offers (:class:`~lagrangian.RecursiveDynamics`), taken in place of closed-form
equations when the rest of the model lets it: see :func:`take`.

The recursion computes the accelerations from the coordinates, their rates and the generalized forces ``τ`` of
every component it does not cover, which store no kinetic energy: ``τ = Q − ∂V/∂q − ∂D/∂q̇`` over those components
(springs, dampers, loads), derived from their energies as usual.  Constraints ``J q̈ = rhs`` (closed loops, and
constraints on positions or velocities, stabilized as the closed form's) add forces ``Jᵀ λ``: the recursion gives
``q̈₀`` and ``Y = M⁻¹ Jᵀ`` (one more pass per constraint), and ``λ`` solves ``(J Y) λ = rhs − J q̈₀``, a system as
small as the number of constraints (:func:`_constrained`).  The closed-form equations of the same model are still
there, derived when something asks for them (display, linearization, the Routhian).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from ..base.domain import Recursion, RecursiveDynamics
from ..base.component import t
from ..errors import ModelError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: A pivot of the recursion at most this fraction of the largest, at a random state, is zero: the motion of that
#: coordinate is not determined by the recursion (a massless end of a chain), and the closed form decides.
PIVOT_FLOOR = 1e-9
EPS = 2.0**-52


@dataclass
class Taken:
    """The recursion a model's equations use: the :class:`~lagrangian.Recursion`, in the equations' plain symbols
    (its ``accelerations`` in the order of the equations' coordinates), and a note for reports."""

    recursion: Recursion
    note: str
    #: the constraints' multipliers ``λ`` (after the accelerations in the solve's unknowns), as the recursion's steps
    multipliers: list = field(default_factory=list)


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
        if (c.constraints or c.velocity_constraints) and not offer.responds:
            return f"component {name!r} adds constraints"
    return None


def position_rows(Phi: sp.Matrix, q, v, w, calc) -> tuple[sp.Matrix, sp.Matrix]:
    """The rows ``J q̈ = rhs`` of constraints on positions ``Φ(q, t) = 0``, stabilized as ``Φ̈ + 2ωΦ̇ + ω²Φ = 0``
    (Baumgarte): ``J = Φ_q`` and ``rhs = −(Φ̇_q q̇ + Φ̇_t + 2ωΦ̇ + ω²Φ)``.  ``Φ̇`` and ``Φ̇_q q̇ + Φ̇_t`` are
    derivatives along ``(q̇, 1)`` (:meth:`~lagrangian.derive.Calculus.along`, ``calc`` the derivation's), one pass
    each over the closure's shared sub-expressions: the Jacobian of ``Φ̇`` took time cubic in a loop's length."""
    rates = {**dict(zip(q, v)), t: sp.S.One}
    Jq = sp.Matrix([[calc.diff(phi, s) for s in q] for phi in Phi]) if len(Phi) else sp.zeros(0, len(q))
    memo: dict = {}
    Phi_dot = [calc.along(phi, rates, memo) for phi in Phi]
    bias = [calc.along(e, rates, memo) for e in Phi_dot]  # (the same direction: Φ̇'s own terms are Φ's)
    return Jq, sp.Matrix([-(b + 2 * w * d + w**2 * phi) for b, d, phi in zip(bias, Phi_dot, Phi)])


def velocity_rows(c: sp.Matrix, q, v, w, calc) -> tuple[sp.Matrix, sp.Matrix]:
    """The rows ``J q̈ = rhs`` of constraints on velocities ``c = A(q, t) q̇ + b(q, t) = 0``, stabilized as
    ``ċ + ω c = 0``: ``J = ∂c/∂q̇`` and ``rhs = −(c_q q̇ + c_t + ω c)``."""
    rates = {**dict(zip(q, v)), t: sp.S.One}
    Jv = sp.Matrix([[calc.diff(e, s) for s in v] for e in c]) if len(c) else sp.zeros(0, len(v))
    memo: dict = {}
    return Jv, sp.Matrix([-(calc.along(e, rates, memo) + w * e) for e in c])


def _constrained(rec: Recursion, J: sp.Matrix, rhs: sp.Matrix) -> tuple[Recursion, list, list]:
    """The tree's accelerations ``a₀`` and responses ``Y = M⁻¹ Jᵀ`` joined by the constraint forces: ``(J Y) λ =
    rhs − J a₀`` solved by ``LDLᵀ`` (``J M⁻¹ Jᵀ`` is symmetric, positive definite where the constraints are
    independent), ``q̈ = a₀ + Y λ``; steps of their own, after the recursion's.  Returns the recursion with those
    accelerations, the multipliers ``λ`` and the solve's pivots over the diagonal they came from (in (0, 1]; zero
    where constraints are redundant)."""
    k, n = J.shape
    defs = list(rec.definitions)

    def step(e):
        if e.is_Atom:
            return e
        d = sp.Dummy("c")
        defs.append((d, e))
        return d

    Y = rec.responses
    S = [[step(sp.Add(*[J[a, i] * Y[b][i] for i in range(n) if J[a, i] != 0 and Y[b][i] != 0])) for b in range(a + 1)]
         for a in range(k)]
    r = [step(rhs[a] - sp.Add(*[J[a, i] * rec.accelerations[i] for i in range(n) if J[a, i] != 0]))
         for a in range(k)]
    L = [[sp.S.Zero] * k for _ in range(k)]
    d, dinv = [sp.S.Zero] * k, [sp.S.Zero] * k
    for j in range(k):
        d[j] = step(S[j][j] - sp.Add(*[L[j][m] ** 2 * d[m] for m in range(j)]))
        # a pivot within rounding of zero (against the diagonal it came from): constraints that are redundant here
        # (exactly zero, or NaN after one: a row no coordinate moves, or a constraint repeated)
        undefined = d[j] == 0 or d[j].has(sp.nan) or S[j][j].has(sp.nan)
        dinv[j] = sp.nan if undefined else step(sp.Piecewise((1 / d[j], d[j] > 16 * k * EPS * S[j][j])))
        for i in range(j + 1, k):
            L[i][j] = step((S[i][j] - sp.Add(*[L[i][m] * L[j][m] * d[m] for m in range(j)])) * dinv[j])
    z = [sp.S.Zero] * k
    for i in range(k):
        z[i] = step(r[i] - sp.Add(*[L[i][m] * z[m] for m in range(i)]))
    lam = [sp.S.Zero] * k
    for i in reversed(range(k)):
        lam[i] = step(z[i] * dinv[i] - sp.Add(*[L[m][i] * lam[m] for m in range(i + 1, k)]))
    qdd = [step(rec.accelerations[i] + sp.Add(*[Y[c][i] * lam[c] for c in range(k) if Y[c][i] != 0]))
           for i in range(n)]
    ratios = [sp.nan if dinv[j] is sp.nan else d[j] / S[j][j] for j in range(k)]
    return Recursion(defs, qdd, rec.kinetic, rec.momenta, rec.pivots), lam, ratios


def take(assembly, eq, Q: list[sp.Expr], calc, constraints=(), velocity=(), rate: float = 10.0) -> Taken | None:
    """The recursion ``eq`` (an :class:`~lagrangian.derivation.equations.Equations` being built) uses, or None for
    the closed-form equations: when a domain offers one, every coordinate is one of its own, every component it
    does not cover stores no kinetic energy (and adds no constraint, unless the domain's recursion takes constraint
    forces), and every pivot is positive at a random state.  ``Q``: the generalized forces of the loads, in
    ``eq``'s plain symbols; ``calc``: the derivation's differentiator; ``constraints`` and ``velocity``: the
    constraints on positions and on velocities, stabilized at ``rate`` as the closed form's are.  A recursion the
    user asked for that cannot serve is refused by name."""
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
    w = sp.Float(rate)
    parts = ([position_rows(sp.Matrix(constraints), q, v, w, calc)] if len(constraints) else []) + \
            ([velocity_rows(sp.Matrix(list(velocity)), q, v, w, calc)] if len(velocity) else [])
    J = sp.Matrix.vstack(*(p[0] for p in parts)) if parts else sp.zeros(0, len(q))
    rhs = sp.Matrix.vstack(*(p[1] for p in parts)) if parts else sp.zeros(0, 1)
    args = [[q[i] for i in order], [v[i] for i in order], [tau[i] for i in order]]
    rec = offer.build(*args, [[J[c, i] for i in order] for c in range(J.rows)]) if J.rows else offer.build(*args)
    place = {i: k for k, i in enumerate(order)}  # the model's coordinate i is the recursion's place[i]

    def ours(values):
        return [values[place[i]] for i in range(len(q))]

    rec = Recursion(rec.definitions, ours(rec.accelerations), rec.kinetic, ours(rec.momenta), ours(rec.pivots),
                    [ours(c) for c in rec.responses])
    multipliers: list = []
    if J.rows:
        rec, multipliers, ratios = _constrained(rec, J, rhs)
    bad = _zero_pivots(rec, eq)
    if bad:
        if offer.forced:
            raise ModelError(f"dynamics='recursive': coordinate(s) {', '.join(bad)} have no inertia about their "
                             f"joints' axes (nothing massive beyond them), so the articulated-body algorithm cannot "
                             f"give their accelerations. Use dynamics='closed' (or 'auto'), which treats them as "
                             f"first-order coordinates when they are damped.")
        return None
    if multipliers:
        out = _at_random(rec.definitions, ratios, eq)
        if out is None or not np.all(out > PIVOT_FLOOR):
            if offer.forced:
                raise ModelError("dynamics='recursive': the constraints are not independent at a random "
                                 "configuration (a loop closed twice, or a constraint given twice), so their forces "
                                 "are not determined. Remove the redundant ones, or use dynamics='closed'.")
            return None
    note = offer.note
    if multipliers:
        k = len(multipliers)
        note = (f"{note}; the forces of {k} constraint{'s' if k > 1 else ''} from a {k} × {k} solve on {k} more "
                f"pass{'es' if k > 1 else ''} of the recursion")
    return Taken(rec, note, multipliers)


def _at_random(definitions, exprs, eq) -> np.ndarray | None:
    """``exprs`` after ``definitions`` at a random state, parameters without values drawn at random within a decade
    of 1 (a model given symbols decides as its twin given numbers); None where they cannot be evaluated."""
    q, v = eq.sym.q, eq.sym.v
    rng = np.random.default_rng(11)
    env: dict = {s: float(x) for s, x in eq._values.items()}
    env |= dict(zip(q, rng.uniform(-0.7, 0.7, len(q)))) | dict(zip(v, rng.uniform(-0.7, 0.7, len(v))))
    try:
        with np.errstate(all="ignore"):
            for s, e in definitions:
                env[s] = _value(e, env, rng)
            return np.array([_value(p, env, rng) for p in exprs], dtype=float)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return None


def _zero_pivots(rec: Recursion, eq) -> list[str]:
    """The coordinates whose pivots are zero (or not finite) at a random state."""
    out = _at_random(rec.definitions, rec.pivots, eq)
    if out is None:
        return list(eq.names)
    finite = np.isfinite(out)
    top = float(np.max(np.abs(out[finite]))) if finite.any() else 0.0
    zero = [eq.names[i] for i in range(len(out)) if finite[i] and not out[i] > PIVOT_FLOOR * top]
    # (a zero pivot makes every pivot nearer the ground not finite: the zero ones are the cause)
    return zero or [eq.names[i] for i in range(len(out)) if not finite[i]]


@functools.cache
def _relations():
    return {sp.StrictGreaterThan: lambda a, b: a > b, sp.GreaterThan: lambda a, b: a >= b,
                  sp.StrictLessThan: lambda a, b: a < b, sp.LessThan: lambda a, b: a <= b}


@functools.cache
def _unary():
    return {sp.sin: np.sin, sp.cos: np.cos, sp.tan: np.tan, sp.exp: np.exp, sp.log: np.log, sp.sqrt: np.sqrt,
              sp.Abs: np.abs}


def _value(e: sp.Expr, env: dict, rng) -> float:
    """``e`` in floats, its symbols from ``env`` (a symbol without a value gets one drawn within a decade of 1)."""
    if e.is_Number:
        return float(e)
    if e.is_Symbol or isinstance(e, (sp.core.function.AppliedUndef, sp.Derivative)):  # (a signal u(t), its rates: values at random)
        if e not in env:
            env[e] = float(10 ** rng.uniform(-0.5, 0.5))
        return env[e]
    if isinstance(e, sp.Piecewise):  # (a recursion's guarded division: NaN where no branch holds)
        for expr, cond in e.args:
            compare = _relations().get(type(cond))
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
    if e.func in _unary():
        return float(_unary()[e.func](args[0]))
    return float(e.xreplace({a: sp.Float(x) for a, x in zip(e.args, args)}))


@functools.cache
def _dual_unary():
    return {sp.sin: (np.sin, np.cos), sp.cos: (np.cos, lambda x: -np.sin(x)), sp.exp: (np.exp, np.exp),
                   sp.tanh: (np.tanh, lambda x: 1 - np.tanh(x) ** 2), sp.log: (np.log, lambda x: 1 / x),
                   sp.atan: (np.arctan, lambda x: 1 / (1 + x * x)), sp.Abs: (np.abs, np.sign)}


def tangents(rec: Recursion, env: dict, q, v, inputs=()) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The accelerations of ``rec`` at a point (``env``: every symbol's value: coordinates, rates, parameters, ``t``),
    their derivatives by the coordinates and the rates (``n × 2n``: ``∂q̈/∂q`` then ``∂q̈/∂q̇``) and those of the
    momenta ``p = M(q) q̇`` (``∂p/∂q = (∂M/∂q) q̇``, then the mass matrix ``∂p/∂q̇``): forward-mode derivatives carried through the recursion's steps, all ``2n`` directions at once, in
    work of the steps' number times ``n`` (the closed form's derivatives grow with its equations, as ``n⁴`` and
    beyond).  ``inputs``: more directions after those (sub-expressions, such as an input's signal ``u(t)``, taken as
    unknowns at 0), whose derivatives follow the rates'.  None where a step holds something this evaluator does
    not know (the closed form then decides)."""
    n = len(q)
    width = 2 * n + len(inputs)
    dual: dict = {}
    for k, s in enumerate([*q, *v, *inputs]):
        tangent = np.zeros(width)
        tangent[k] = 1.0
        dual[s] = (float(env[s]) if k < 2 * n else 0.0, tangent)
    try:
        with np.errstate(all="ignore"):
            for s, e in rec.definitions:
                dual[s] = _dual(e, dual, env)
            acc = [_dual(e, dual, env) for e in rec.accelerations]
            momenta = [_dual(e, dual, env) for e in rec.momenta]
    except (TypeError, ValueError, KeyError, ZeroDivisionError, OverflowError):
        return None

    def grad(x):
        return x[1] if x[1] is not None else np.zeros(width)

    qdd = np.array([a[0] for a in acc])
    J = np.array([grad(a) for a in acc]).reshape(n, width)
    P = np.array([grad(p) for p in momenta]).reshape(n, width)
    return qdd, J, P


def _dual(e, dual: dict, env: dict):
    """``(value, tangent or None)`` of ``e`` (its symbols' from ``dual``, else constants from ``env``)."""
    if e in dual:
        return dual[e]
    if e.is_Number:
        return float(e), None
    if e.is_Symbol:
        return float(env[e]), None
    if isinstance(e, sp.Piecewise):
        for expr, cond in e.args:
            compare = _relations().get(type(cond))
            if cond is sp.true or (compare is not None and compare(_dual(cond.lhs, dual, env)[0],
                                                                    _dual(cond.rhs, dual, env)[0])):
                return _dual(expr, dual, env)
        return float("nan"), None
    args = [_dual(a, dual, env) for a in e.args]
    if e.is_Add:
        moving = [a[1] for a in args if a[1] is not None]
        return float(sum(a[0] for a in args)), (sum(moving[1:], moving[0].copy()) if moving else None)
    if e.is_Mul:
        value = float(np.prod([a[0] for a in args]))
        tangent = None
        for k, (_, tk) in enumerate(args):
            if tk is not None:
                others = float(np.prod([a[0] for j, a in enumerate(args) if j != k]))
                tangent = tk * others if tangent is None else tangent + tk * others
        return value, tangent
    if e.is_Pow:
        (b, tb), (x, tx) = args
        value = float(np.float64(b) ** x)
        if tx is not None:
            raise ValueError("a power with a moving exponent")
        return value, (None if tb is None else tb * (x * np.float64(b) ** (x - 1)))
    if e.func in _dual_unary() and len(args) == 1:
        f, df = _dual_unary()[e.func]
        (x, tx), = args
        return float(f(x)), (None if tx is None else tx * float(df(x)))
    raise ValueError(f"no forward rule for {e.func}")
