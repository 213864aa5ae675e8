"""Operating points: the equilibria of a model, every branch, each with its stability verdict.

An equilibrium is a state at rest (``q̇ = 0``, inputs at their values at
``t₀``) where the forces balance: ``f(q) + Φ_qᵀ λ = 0`` with ``Φ(q) = 0``
for a model with loop constraints.  :func:`equilibria` solves these
equations with SymPy (every real branch it finds, under a time budget per attempt), or
from a starting guess ``near=`` by Newton's method, and judges each
branch from the eigenvalues of the model linearized there
(:mod:`lagrangian.analysis.linearize`):

- *unstable*: an eigenvalue with a positive real part;
- *marginal*: a zero eigenvalue (a bifurcation, or a neutral direction such
  as a free coordinate): the linearization cannot decide;
- *asymptotically stable*: every eigenvalue with a negative real part;
- *stable*: every mode oscillates, the stiffness is symmetric and positive
  definite (a strict minimum of the potential, which the energy then
  bounds); *marginal* when it is not (gyroscopic or circulatory forces).

Angles are given in (−π, π].  Decisions use tolerances relative to the
spectrum, never ``== 0``.
Steady motions of models with ignorable coordinates are the equilibria of
their Routhian reduction (``lagrangian.routh``): ``equilibria`` and
:func:`lagrangian.frequency.modes` take a reduced model too.

>>> import lagrangian as lg
>>> m = lg.Model("pendulum", dim=2)
>>> _ = m.add("rod", "r", "r", m=0.3, length=0.7)
>>> _ = m.add("revolute", "j", ("ground", "r"), absolute=True)
>>> _ = m.add("gravity", "g")
>>> [(round(e.point["theta_j"], 6), e.stability.verdict) for e in equilibria(m)]
[(-1.570796, 'stable'), (1.570796, 'unstable')]
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..base.budget import DEFAULT_SECONDS, BudgetExceeded, within
from ..base.component import t
from ..errors import ModelError, UnknownNameError
from ..model import Model
from ..numerics.problem import balance
from .frequency import modes
from .linearize import linearize
from .modes import Modes
from .routh.stability import Stability, _fmt
from .routh.steady import _is_angle
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["Equilibrium", "equilibria"]


@dataclass
class Equilibrium:
    """One equilibrium: coordinate values ``point``, the :class:`~lagrangian.routh.Stability` verdict (with the
    eigenvalues) and the natural :class:`~lagrangian.frequency.Modes` there."""

    point: dict[str, float]
    stability: Stability
    modes: Modes

    def __repr__(self) -> str:
        where = ", ".join(f"{k} = {v:.6g}" for k, v in self.point.items())
        return f"<Equilibrium {where}: {self.stability.verdict}>"


def equilibria(model: Model, *, params: Mapping[str, float] | None = None, time: float = 0.0,
               near: Mapping[str, float] | None = None, budget: float | None = DEFAULT_SECONDS) -> list[Equilibrium]:
    """Every equilibrium of ``model`` SymPy finds (or the one Newton's method reaches from ``near``), sorted by
    coordinate values, each with its stability verdict.

    ``params`` gives values to symbolic parameters (every parameter needs
    one); ``time`` is the instant ``t₀`` of a model that depends on time.
    When SymPy cannot solve within ``budget`` seconds, a
    :class:`~lagrangian.errors.ModelError` says so and asks for ``near=``.
    """
    if not isinstance(model, Model):
        raise ModelError(f"equilibria takes a lagrangian.Model, got {type(model).__name__}.")
    model._holonomic_only("the search for equilibria")
    model._no_state_callables("the search for equilibria")
    eq = model.eq
    names, q, v = eq.names, list(eq.sym.q), list(eq.sym.v)
    values = model._values(dict(params or {}), overrides=True)
    subs = {s: sp.Float(x) for s, x in values.items()}
    subs.update({vs: sp.Integer(0) for vs in v})
    subs[t] = sp.Float(float(time))
    f = [e.xreplace(subs) for e in eq.f]
    Phi = [c.xreplace(subs) for c in eq.constraints]
    lam = [sp.Dummy(f"lambda{k}", real=True) for k in range(len(Phi))]
    exprs = [fi + sum(lk * sp.diff(c, qi) for lk, c in zip(lam, Phi)) for fi, qi in zip(f, q)] + Phi
    unknowns = q + lam
    leftover = sorted({str(s) for e in exprs for s in e.free_symbols} - {str(u) for u in unknowns})
    if leftover:
        raise ModelError(f"model {model.name!r}: its equilibrium equations still hold {', '.join(leftover)}; "
                         f"give them values in params=.")
    angles = [_is_angle(c) for c in eq.coordinates]
    if near is not None:
        points = [_newton(model.name, names, exprs, unknowns, near)]
    else:
        # first with the unknowns declared real (fast on trigonometric equations); when that finds nothing, again
        # without assumptions: SymPy drops real roots it writes through complex numbers (a cubic's casus
        # irreducibilis) when the unknowns are declared real.  The branches are filtered numerically below.
        # The numbers go in as the rationals they print as: SymPy solves exact equations many times faster
        # (13 s against 0.7 s for a spherical pendulum's steady motions), and the branches' floats agree to rounding.
        exact = [sp.nsimplify(e, rational=True) for e in exprs]
        live = [e for e in exact if e != 0]
        if any(not (e.free_symbols & set(unknowns)) for e in live):
            return []  # a force that no configuration balances (a constant one on a free mass)
        free = [n for n, u in zip(names, q) if not any(e.has(u) for e in live)]
        if free:  # no equation holds it: it rests anywhere (solve would give no branch at all)
            raise ModelError(_continuum(model.name, free))
        try:
            found = within(_branches, exact, unknowns, seconds=budget)
        except BudgetExceeded:
            found = None
        if not found:
            plain = [sp.Dummy(u.name) for u in unknowns]
            try:
                again = within(_branches, [e.xreplace(dict(zip(unknowns, plain))) for e in exact], plain, seconds=budget)
            except BudgetExceeded:
                again = None
            if again is not None:
                found = [{u: sol[p] for u, p in zip(unknowns, plain) if p in sol} for sol in again]
        if found is None:
            raise ModelError(f"model {model.name!r}: SymPy did not solve its equilibrium equations within the budget of "
                             f"{budget:g} s; give a starting guess, near={{{', '.join(f'{n!r}: ...' for n in names)}}}, "
                             f"or raise budget=.")
        points = []
        for sol in found:
            if not all(u in sol for u in q):
                raise ModelError(_continuum(model.name, [n for n, u in zip(names, q) if u not in sol]))
            point = {n: _real(sol[u]) for n, u in zip(names, q)}
            if any(x is None for x in point.values()):
                continue  # a complex branch
            point = {n: _wrapped(x) if angle else x for (n, x), angle in zip(point.items(), angles)}
            if all(np.isfinite(list(point.values()))) and not any(_same(point, p) for p in points):
                points.append(point)
    out = []
    for point in sorted(points, key=lambda p: tuple(p.values())):
        lin = linearize(model, at=point, inputs=[], params=params, time=time, symbolic=False)
        found_modes = modes(lin)
        out.append(Equilibrium(point, _verdict(lin, found_modes), found_modes))
    return out


def _continuum(model: str, free: list[str]) -> str:
    return (f"model {model!r} has a continuum of equilibria (a free coordinate): {', '.join(free)} can take any "
            f"value. Fix it, or give near= to pick one.")


def _branches(exprs: list[sp.Expr], unknowns: list[sp.Symbol]) -> list[dict] | None:
    """Every solution SymPy finds, or None when it cannot solve.

    Polynomial equations (an electrostatic actuator's, a spring network's) go to ``solve_poly_system`` (a
    Gröbner basis, then the roots of one polynomial): every complex root, none dropped through a cubic's
    casus irreducibilis, in 6 ms where ``solve`` took 300 ms on the actuator of ``tests/test_operating.py``.
    The rest, and a system with a continuum of solutions, go to ``solve``."""
    if all(e.is_polynomial(*unknowns) for e in exprs):
        try:
            found = sp.solve_poly_system(exprs, *unknowns)
        except (NotImplementedError, ValueError, TypeError, sp.PolynomialError):
            found = None
        if found is not None:
            return [dict(zip(unknowns, roots)) for roots in found]
    try:
        return sp.solve(exprs, unknowns, dict=True)
    except (NotImplementedError, ValueError, TypeError):
        return None


def _real(value: sp.Expr) -> float | None:
    """A branch's value as a float; ``None`` when it is complex.  The roots of a cubic with three real roots come
    out of SymPy through complex numbers (casus irreducibilis): an imaginary part within rounding of the value is
    rounding."""
    try:
        z = complex(sp.N(value, 30))
    except TypeError:
        return None
    return z.real if abs(z.imag) <= 1e-12 * max(abs(z.real), 1e-300) or z.imag == 0 else None


def _wrapped(angle: float) -> float:
    """An angle in (−π, π]."""
    out = float(np.remainder(angle + np.pi, 2 * np.pi) - np.pi)
    return np.pi if out == -np.pi else out


def _same(a: Mapping[str, float], b: Mapping[str, float]) -> bool:
    return all(abs(a[k] - b[k]) <= 1e-9 * max(1.0, abs(a[k])) for k in a)


def _newton(model: str, names: list[str], exprs: list[sp.Expr], unknowns: list[sp.Symbol],
            near: Mapping[str, float]) -> dict[str, float]:
    import scipy.optimize

    unknown = [k for k in near if k not in names]
    if unknown:
        raise UnknownNameError("coordinate", unknown[0], names)
    x0 = np.array([float(near.get(n, 0.0)) for n in names] + [0.0] * (len(unknowns) - len(names)))
    F = sp.lambdify([unknowns], exprs, "numpy")
    J = sp.lambdify([unknowns], sp.Matrix(exprs).jacobian(unknowns), "numpy")
    sol = scipy.optimize.root(lambda x: np.asarray(F(x), dtype=float), x0, jac=lambda x: np.asarray(J(x), dtype=float),
                              method="hybr")
    residual = float(np.max(np.abs(np.asarray(F(sol.x), dtype=float)), initial=0.0))
    scale = float(np.max(np.abs(np.asarray(J(sol.x), dtype=float)), initial=1.0)) * max(1.0, float(np.max(np.abs(sol.x))))
    if not sol.success or residual > 1e-9 * scale:
        raise ModelError(f"model {model!r}: no equilibrium found from near={dict(near)} (residual {residual:.3g} after "
                         f"{sol.nfev} evaluations: {sol.message}); start from another guess.")
    return {n: float(x) for n, x in zip(names, sol.x)}


def _regular_at_zero(lin) -> bool:
    """Whether the linearization's pencil is clearly nonsingular at ``s = 0`` (so no eigenvalue is zero): the
    stiffness, bordered by the constraint Jacobian, balanced, with its smallest singular value above 1e-12 of its
    largest (a zero eigenvalue, simple or of a Jordan block, leaves it singular to round-off)."""
    K, Phi = np.asarray(lin.K, dtype=float), np.asarray(lin.Phi, dtype=float)
    m = Phi.shape[0] if Phi.ndim == 2 else 0
    P = np.block([[K, Phi.T], [Phi, np.zeros((m, m))]]) if m else K
    if not P.size or not np.all(np.isfinite(P)):
        return False
    balanced, _ = balance(P)
    sv = np.linalg.svd(balanced, compute_uv=False)
    return bool(sv[0] > 0 and sv[-1] > 1e-12 * sv[0])


def _verdict(lin, found: Modes) -> Stability:
    lam = found.eigenvalues
    every = np.concatenate([lam, np.conj(lam[np.abs(lam.imag) > 0])]) if lam.size else lam
    scale = float(np.max(np.abs(every), initial=0.0))
    tol = 1e-7 * scale
    freqs = np.sort(np.abs(lam.imag[lam.imag > tol]))
    K = lin.K
    if lin.Phi.shape[0]:  # the stiffness on the motions the constraints allow
        _, sv, vt = np.linalg.svd(lin.Phi)
        free = vt[int(np.sum(sv > 1e-10 * max(sv.max(initial=0.0), 1.0))):].T
        K = free.T @ K @ free
    symmetric = np.allclose(K, K.T, rtol=1e-9, atol=1e-12 * float(np.max(np.abs(K), initial=0.0)))
    curvature = np.linalg.eigvalsh((K + K.T) / 2) if K.size else np.zeros(0)
    minimum = bool(K.size) and symmetric and bool(np.all(curvature > 1e-9 * float(np.max(np.abs(curvature)))))
    # A small eigenvalue (|λ| ≤ 1e-7 of the largest: a slow pole beside fast ones, an RC of 1e3 s beside a
    # resonance at 1e4 rad/s) is a zero only if the pencil is singular at s = 0; where it is not, its sign is as
    # sure as its real part is large against round-off, and decides.
    small = np.abs(lam) <= tol
    sure = small & (np.abs(lam.real) > np.maximum(1e-6 * np.abs(lam), 1e3 * np.finfo(float).eps * scale))
    if small.any() and _regular_at_zero(lin):
        small = small & ~sure
    else:
        sure = np.zeros_like(small)
    if scale > 0 and np.any((lam.real > tol) | (sure & (lam.real > 0))):
        return Stability("unstable", lam, freqs, curvature,
                         f"an eigenvalue with positive real part ({_fmt(lam[np.argmax(lam.real)])})")
    if scale == 0 or np.any(small):
        return Stability("marginal", lam, freqs, curvature,
                         "a zero eigenvalue: the linearization cannot decide (a bifurcation, or a neutral direction)")
    if np.all((lam.real < -tol) | (sure & (lam.real < 0))):
        return Stability("asymptotically stable", lam, freqs, curvature, "every eigenvalue has a negative real part")
    if minimum and not np.any(lin.C):
        return Stability("stable", lam, freqs, curvature,
                         "every mode oscillates and the potential has a strict minimum: the energy bounds the motion")
    return Stability("marginal", lam, freqs, curvature,
                     "the linearized motion oscillates without growth, but the stiffness is not a symmetric positive "
                     "definite one (gyroscopic or circulatory forces): linear analysis is inconclusive")
