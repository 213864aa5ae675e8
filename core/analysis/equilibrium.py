"""Whether an operating point is an equilibrium, for :func:`~lagrangian.analysis.linearize.linearize`.

Newton's method to a rest point from the origin (SPICE's operating point), and
the checks that refuse a point by name: a net force at rest (or in steady
motion, given rates), a kinematic loop left open, rates that violate the
constraints on velocities, and the multipliers that hold a constrained point.
"""

from __future__ import annotations

import numpy as np

from ..base.identity import is_zero
from ..errors import ModelError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["check_closure", "check_rest", "check_rolling", "multipliers", "settle"]


def settle(f_u, slopes, q, names, point, subs, at_point, n) -> None:
    """With no point given: Newton's method from the origin on ``f(q) = 0`` at rest (SPICE's operating point), the
    point and ``subs`` moved to where it converges; left at the origin when it does not (the rest check then says
    so).  ``slopes()``: ``{(i, j): ∂f_i/∂q_j}`` at the current point.  A linear model converges in one step, or
    is left where it is (no rest point: a DC current flows)."""
    x = np.array([float(point[nm]) for nm in names])
    for _ in range(50):
        f = np.array([at_point(e) for e in f_u])
        K = np.zeros((n, n))
        for (i, j), value in slopes().items():
            K[i, j] = -value
        scale = max(float(np.abs(K).max(initial=0.0)) * max(1.0, float(np.abs(x).max(initial=0.0))), 1e-300)
        if np.abs(f).max(initial=0.0) <= 1e-12 * scale:
            break
        step, *_ = np.linalg.lstsq(K, f, rcond=None)
        if not np.all(np.isfinite(step)) or np.abs(K @ step - f).max() > 1e-9 * max(np.abs(f).max(), 1e-300):
            x = None  # no rest point (a singular stiffness the forces do not balance)
            break
        x = x + step
        for qs, nm, value in zip(q, names, x):
            point[nm] = sp.Float(value)
            subs[qs] = point[nm]
    else:
        x = None
    if x is None:
        for qs, nm in zip(q, names):
            point[nm] = sp.Integer(0)
            subs[qs] = point[nm]


def _scale(K0, M0, point, names) -> float:
    K = np.abs(np.asarray(K0, dtype=float) if isinstance(K0, np.ndarray) else np.array(K0.tolist(), dtype=float))
    x = max([abs(float(point[nm])) for nm in names] + [1.0])
    return float(K.max() * x) if K.size else 1.0


def _not_steady(model: str, moving) -> str:
    """The start of the message refusing a point that is not an equilibrium (a steady motion, given rates)."""
    if moving:
        return f"model {model!r} is not in steady motion at this point and these rates"
    return f"model {model!r} is not at rest at this operating point"


def _give(moving) -> str:
    return ("Give at= and velocity= a steady motion (a point and rates where every rate stays constant)" if moving
            else "Give at= an equilibrium")


def check_rest(model: str, f0, names, symbolic: bool, tol: float, K0, M0, point, moving=None) -> None:
    """Refuse a point where the net forces ``f0`` do not vanish (beyond ``tol`` of the stiffness scale; exactly,
    when ``symbolic``), naming the coordinates that would accelerate."""
    if symbolic:
        accelerating = [nm for nm, e in zip(names, f0) if not is_zero(e)]
        if accelerating:
            i = names.index(accelerating[0])
            raise ModelError(f"{_not_steady(model, moving)}: the equation of {accelerating[0]!r} has a net force "
                             f"{f0[i]} there. {_give(moving)}.")
        return
    residual = np.abs(np.array([float(e) for e in f0]))
    scale = _scale(K0, M0, point, names)
    bad = [nm for nm, r in zip(names, residual) if r > tol * max(scale, 1e-300)]
    if bad:
        worst = int(np.argmax(residual))
        raise ModelError(f"{_not_steady(model, moving)}: the net force on {', '.join(bad)} is {residual[worst]:.3g} "
                         f"(against a stiffness scale of {scale:.3g}). {_give(moving)} (the coordinates' values where "
                         f"the forces balance).")


def check_closure(model: str, residual, symbolic: bool, tol: float) -> None:
    """Refuse a point that leaves a kinematic loop open (``residual``: the constraints ``Φ`` there)."""
    if symbolic:
        if any(not is_zero(r) for r in residual):
            raise ModelError(f"model {model!r}: the operating point does not close the model's kinematic loops "
                             f"(Φ = {residual}). Give at= a point that satisfies them.")
        return
    worst = max((abs(r) for r in residual), default=0.0)
    if worst > tol:
        raise ModelError(f"model {model!r}: the operating point does not close the model's kinematic loops "
                         f"(|Φ| = {worst:.3g}). Give at= a point that satisfies them.")


def check_rolling(model: str, residual, owners, Av, moving, symbolic: bool, tol: float) -> None:
    """Refuse rates that violate the constraints on velocities, naming their components."""
    if symbolic:
        held = sorted({o for o, r in zip(owners, residual) if not is_zero(r)})
        worst = ""
    else:
        speed = max([abs(float(x)) for x in moving.values()] + [1.0])
        scale = speed * max(float(np.abs(np.asarray(Av, dtype=float)).max(initial=0.0)), 1.0)
        held = sorted({o for o, r in zip(owners, residual) if abs(r) > tol * scale})
        worst = f" (|c| = {max((abs(r) for r in residual), default=0.0):.3g})"
    if held:
        raise ModelError(f"model {model!r}: the rates given violate the constraints on velocities of "
                         f"{', '.join(map(repr, held))}{worst}. Give velocity= rates that satisfy them "
                         f"(lagrangian.plugins.multibody.consistent_initial solves the dependent ones).")


def multipliers(model: str, f0, Jq, symbolic: bool, names, tol: float, K0, point, check: bool = True, moving=None):
    """The multipliers ``λ₀`` with ``f₀ + Wᵀ λ₀ = 0`` (``W`` the directions the constraints' forces act along), or
    an error when none holds the point at rest (in steady motion, given ``moving`` rates)."""
    if symbolic:
        JT = Jq.T
        lam = (JT.T * JT).LUsolve(-JT.T * f0)
        rest = f0 + JT * lam
        if check and any(not is_zero(r) for r in rest):
            raise ModelError(f"{_not_steady(model, moving)}: the constraints cannot balance the net forces "
                             f"{list(rest)}. {_give(moving)}.")
        return list(lam)
    J = np.asarray(Jq, dtype=float)
    f = np.array([float(e) for e in f0])
    lam, *_ = np.linalg.lstsq(J.T, -f, rcond=None)
    rest = f + J.T @ lam
    scale = max(_scale(K0, None, point, names), float(np.abs(f).max(initial=0.0)))
    if check and np.abs(rest).max(initial=0.0) > tol * max(scale, 1e-300):
        i = int(np.argmax(np.abs(rest)))
        raise ModelError(f"{_not_steady(model, moving)}: a net force {rest[i]:.3g} on {names[i]!r} that the "
                         f"constraints do not balance. {_give(moving)}.")
    return [sp.Float(x) for x in lam]
