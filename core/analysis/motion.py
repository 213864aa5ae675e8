"""Linearization about a steady motion, and Kane's state space of a model with constraints on velocities.

A *steady motion* is a state whose rates stay constant: ``q̈ = 0`` with the
rates ``q̇₀`` given (:func:`~lagrangian.analysis.linearize.linearize`'s
``velocity=``).  A coordinate that moves (``q̇₀ ≠ 0``) must be absent from the
equations (ignorable, cyclic: a bicycle's position, heading and wheel
angles), so that the linearization does not change as it advances; the
others stay where they are.  Small motions about it obey the Laplace form of
:class:`~lagrangian.analysis.linearize.LinearModel`, with ``C = −∂f/∂q̇`` and
``K = −∂f/∂q`` taken at the moving state (gyroscopic and centripetal terms
included).

Constraints on velocities ``A(q, t) q̇ + b(q, t) = 0`` (rolling without
slipping, knife edges) enter the Laplace form as rows ``(∂(A q̇ + b)/∂q +
A s) δq = 0`` whose multipliers act along ``A`` (Lagrange–d'Alembert): the
pencil's finite eigenvalues are those of the motion on the constraints.
:func:`kane_state_space` gives its state space the way Kane's method does:
independent coordinates ``δq_i`` (the holonomic constraints solved for the
others), independent speeds ``δu`` (the constraints on velocities solved for
the dependent speeds), and the equations of motion projected on the
directions the constraints allow, where their multipliers do no work.

>>> import lagrangian as lg
>>> from lagrangian.frequency import linearize
>>> sled = lg.Model("Chaplygin sleigh", dim=2)
>>> _ = sled.add("body", "b", "b", m=0.3, inertia=2e-3, points={"edge": (-0.05, 0.0)})
>>> _ = sled.add("free", "j", ("ground", "b"))
>>> _ = sled.add("knife_edge", "k", "b.edge")
>>> lin = linearize(sled, velocity={"x_j": 0.4})       # gliding straight along +x at 0.4 m/s
>>> A, B, C, D, states = lin.state_space()
>>> states
['x_j', 'y_j', 'theta_j', "x_j'", "theta_j'"]
>>> import numpy as np
>>> round(float(np.linalg.eigvals(A).real.min()), 6), round(-0.3 * 0.05 * 0.4 / (2e-3 + 0.3 * 0.05**2), 6)
(-2.181818, -2.181818)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from ..base.identity import depends_on
from ..errors import ModelError, UnknownNameError
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["kane_state_space", "null_space", "number", "rates", "steady_check"]


def rates(model, names: Sequence[str], velocity: Mapping[str, Any] | None) -> dict[str, Any]:
    """The rates of a steady motion, ``velocity=`` checked: coordinate names to finite numbers (exact SymPy numbers
    kept, symbols allowed for a symbolic linearization); only the nonzero ones are returned."""
    if velocity is None:
        return {}
    if not isinstance(velocity, Mapping):
        raise ModelError(f"velocity= is a mapping of coordinate names to rates, got {type(velocity).__name__}.")
    eliminated = model.assembly.eliminated
    first = {model.eq.names[i] for i in model.eq.first_order}
    out: dict[str, Any] = {}
    for key, val in velocity.items():
        if key in eliminated:
            raise eliminated[key].refusal("velocity", f"the rate of {key} follows")
        if key not in names:
            raise UnknownNameError("coordinate", key, list(names))
        if key in first:
            raise ModelError(f"velocity[{key!r}]: {key!r} is a first-order coordinate (no inertia), whose rate follows "
                             f"from the equations; leave it out of velocity=.")
        x = number("velocity", key, val)
        if not (x.is_number and x == 0):
            out[key] = x
    return out


def number(argument: str, key: str, val: Any) -> sp.Expr:
    """``argument[key]`` (a point's coordinate, a motion's rate) as SymPy: a symbol or expression kept, an exact real
    number kept exact (−π/2: a symbolic linearization then finds the rest it has there exactly), a plain number a
    Float (an exact 0 for zero); anything not finite, or not a number, a :class:`ModelError` naming it."""
    if isinstance(val, sp.Basic) and not val.is_number:
        return val
    try:
        x = float(val)
    except (TypeError, ValueError):
        raise ModelError(f"{argument}[{key!r}] must be a number, got {val!r:.80}.") from None
    if not np.isfinite(x):
        raise ModelError(f"{argument}[{key!r}] must be finite, got {val!r:.80}.")
    return val if isinstance(val, sp.Basic) and val.is_real else sp.Float(x) if x else sp.Integer(0)


def steady_check(model: str, names: Sequence[str], q: Sequence[sp.Symbol], moving: Mapping[str, Any],
                 expressions: Sequence[Any], values: Mapping[Any, Any], diff: Callable) -> None:
    """Refuse a motion whose moving coordinates the equations depend on (``expressions``: the mass matrix, the
    forcing, the constraints; each dependence decided by :func:`~lagrangian.base.identity.depends_on`, so that a
    rotation's ``cos² ψ + sin² ψ`` is no dependence on ``ψ``): its linearization would change as they advance."""
    if not moving:
        return
    held = []
    for nm, qs in zip(names, q):
        if nm in moving and any(depends_on(e, qs, values, diff=diff) for e in expressions):
            held.append(nm)
    if held:
        raise ModelError(f"model {model!r}: {', '.join(map(repr, held))} move at the given rates but the equations "
                         f"depend on {'it' if len(held) == 1 else 'them'}, so the motion is not steady (its "
                         f"linearization changes as they advance). Give rates only to ignorable coordinates (absent "
                         f"from the equations: a position, a heading, a wheel's angle), or linearize at rest.")


def null_space(J: np.ndarray, n: int) -> tuple[list[int], list[int], np.ndarray]:
    """``(dependent, independent, N)`` of the rows ``J x = 0`` in ``n`` unknowns: the dependent unknowns are those
    whose columns are best conditioned (QR with column pivoting), ``x = N x_independent`` (redundant rows solved
    exactly, by least squares)."""
    import scipy.linalg

    if not J.shape[0]:
        return [], list(range(n)), np.eye(n)
    _, R, pivots = scipy.linalg.qr(J, pivoting=True)
    rank = int(np.sum(np.abs(np.diag(R)) > 1e-10 * max(np.abs(R).max(initial=0.0), 1e-300)))
    dependent, free = sorted(pivots[:rank]), sorted(pivots[rank:])
    N = np.zeros((n, len(free)))
    N[free, np.arange(len(free))] = 1.0
    N[dependent] = np.linalg.lstsq(J[:, dependent], -J[:, free], rcond=None)[0]
    return dependent, free, N


def kane_state_space(lin) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """``(A, B, C, D, states)`` of a linearization with constraints on velocities, in Kane's independent
    coordinates and speeds.

    With ``H δq = 0`` the holonomic constraints, ``J δq̇ + G δq = 0`` all
    the constraints at the level of velocities (``J = [H; A]``), ``δq = N_h
    δq_i`` and ``δq̇ = N_v δu + P δq`` (the dependent speeds solved), the
    state is ``x = (δq_i, δu)``:

    - ``δq̇_i = (P N_h δq_i + N_v δu)_i``;
    - ``N_vᵀ M N_v δu̇ = N_vᵀ (B u − K δq − C δq̇ − M P δq̇)``, the
      constraint forces gone (``N_vᵀ Jᵀ = 0``).

    The outputs' rows ``Σ_k Cq_k s^k δq`` are read from ``δq``, ``δq̇`` and
    ``δq̈ = N_v δu̇ + P δq̇``.  Numeric linearizations only; inputs through
    their derivatives or integral, and first-order coordinates, are refused
    as :meth:`~lagrangian.analysis.linearize.LinearModel.state_space` refuses them.
    """
    name = lin.model
    if lin.symbolic:
        raise ModelError(f"model {name!r}: the state space of a symbolic linearization with constraints on velocities "
                         f"is not formed; give the parameters values (params=), or use the Laplace form.")
    if lin.first_order:
        raise ModelError(f"model {name!r}: first-order coordinates ({', '.join(lin.first_order)}) beside constraints "
                         f"on velocities have no state-space form here; use the transfer function.")
    if np.any(lin.Bi) or np.any(lin.Di) or any(np.any(b) for b in lin.B[1:]) or any(np.any(d) for d in lin.D[1:]):
        raise ModelError(f"model {name!r}: inputs {', '.join(lin.inputs)} enter through their derivatives or their "
                         f"integral, so ẋ = A x + B u has no B; use the transfer function, in which s u is exact.")
    n, k = len(lin.coordinates), lin.velocity_rows
    h = lin.Phi.shape[0] - k
    J = lin.force_rows()
    G = np.vstack([np.zeros((h, n)), lin.Phi[h:]])
    _, free_q, Nh = null_space(lin.Phi[:h], n)
    dependent, free_v, Nv = null_space(J, n)
    P = np.zeros((n, n))
    if dependent:
        P[dependent] = np.linalg.lstsq(J[:, dependent], -G, rcond=None)[0]
    PN = P @ Nh
    A11, A12 = PN[free_q], Nv[free_q]
    Mbar = Nv.T @ lin.M @ Nv
    if Mbar.size and np.linalg.cond(Mbar) > 1e14:
        raise ModelError(f"model {name!r}: the mass matrix on the speeds the constraints allow is singular here, so "
                         f"the linearization has no state-space form at this point.")
    MP = lin.M @ PN
    A21 = np.linalg.solve(Mbar, Nv.T @ (-lin.K @ Nh - lin.C @ PN - MP @ A11)) if Mbar.size else np.zeros((0, len(free_q)))
    A22 = np.linalg.solve(Mbar, Nv.T @ (-lin.C @ Nv - MP @ A12)) if Mbar.size else np.zeros((0, 0))
    B2 = np.linalg.solve(Mbar, Nv.T @ lin.B[0]) if Mbar.size else np.zeros((0, len(lin.inputs)))
    A = np.block([[A11, A12], [A21, A22]])
    B = np.vstack([np.zeros((len(free_q), len(lin.inputs))), B2])
    Cq = list(lin.Cq) + [np.zeros_like(lin.Cq[0])] * (3 - len(lin.Cq))
    # δq = [N_h 0] x, δq̇ = [P N_h  N_v] x, δq̈ = N_v (A₂ x + B₂ u) + P N_h (A₁ x)
    pos = np.hstack([Nh, np.zeros((n, len(free_v)))])
    rate = np.hstack([PN, Nv])
    acc = Nv @ np.hstack([A21, A22]) + PN @ np.hstack([A11, A12])
    C = Cq[0] @ pos + Cq[1] @ rate + Cq[2] @ acc
    D = lin.D[0] + Cq[2] @ Nv @ B2
    states = [lin.coordinates[i] for i in free_q] + [f"{lin.coordinates[j]}'" for j in free_v]
    return A, B, C, D, states
