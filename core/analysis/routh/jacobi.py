"""The Jacobi integral ``h = Σ q̇ ∂L/∂q̇ − L`` of a model: whether it is conserved, and how it differs from ``T + V``.

:func:`jacobi_integral` forms ``h`` on the generic energies (once per
structure) and gives the reasons it is or is not conserved (explicit time
dependence, dissipation, generalized forces, moving constraints);
:class:`JacobiIntegral` holds the result and measures its drift along a simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ...base.component import t
from ...base.identity import equal, is_zero, nodes
from ...model import Model
from ...numerics.simulation import Result
from .cache import _by_structure, _put
from .cyclic import _depends, _named
from .tidy import _tidy
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class JacobiIntegral:
    """``h = Σ q̇ ∂L/∂q̇ − L`` of a model, whether it is conserved, and how it differs from ``T + V``."""

    model: Model = field(repr=False)
    expr: sp.Expr  # h, in q(t), q̇(t)
    energy: sp.Expr  # T + V
    difference: sp.Expr  # h − (T + V)
    conserved: bool
    reasons: list[str]

    @property
    def energy_conserved(self) -> bool:
        """Whether the total energy ``T + V`` is conserved too (``h`` conserved and equal to it)."""
        return self.conserved and self.difference == 0

    def __str__(self) -> str:
        state = "conserved" if self.conserved else "not conserved"
        same = "equal to the total energy T + V" if self.difference == 0 else f"h − (T + V) = {sp.sstr(self.difference)}"
        return f"Jacobi integral h = {sp.sstr(self.expr)}: {state} ({'; '.join(self.reasons)}); {same}"

    def values(self, result: Result) -> np.ndarray:
        """``h`` along a simulation of the model."""
        return result.quantity(self.expr)

    def drift(self, result: Result) -> float:
        """Largest change of ``h`` along ``result``, relative to ``max(|h₀|, max T)``."""
        h = self.values(result)
        scale = max(abs(float(h[0])), float(np.max(np.abs(result.T))), 1e-300)
        return float(np.max(np.abs(h - h[0]))) / scale


def _without_residues(expr: sp.Expr, reference: sp.Expr) -> sp.Expr:
    """``expr`` without the terms that are round-off residues (dropping them keeps it equal to ``reference``)."""
    terms = list(sp.Add.make_args(expr))
    if len(terms) > 50:
        return expr
    for term in sorted(terms, key=lambda e: min((abs(float(f)) for f in e.atoms(sp.Float)), default=math.inf)):
        if not term.atoms(sp.Float):
            break
        rest = [e for e in terms if e is not term]
        if equal(sp.Add(*rest), reference):
            terms = rest
    return sp.Add(*terms)


#: The Jacobi integral of more distinct sub-expressions than this is not multiplied out (``expand``) for display:
#: a chain's nested velocities multiply out exponentially (0.26 s at 5 planar links, 198 sub-expressions; 5.6 s at
#: 10; more than a minute at 20; 18 s at 3 bodies on spherical joints, minutes at 5).  Whether it equals ``T + V`` is
#: decided at random points as everywhere else (:func:`lagrangian.identity.equal`), and it is then shown as ``T + V``.
EXPAND_MAX = 250


def jacobi_integral(model: Model) -> JacobiIntegral:
    """The Jacobi integral ``h = Σ q̇ ∂L/∂q̇ − L`` of ``model`` and whether it is conserved.

    ``dh/dt = −∂L/∂t + Σ Q q̇ − Σ q̇ ∂D/∂q̇``: ``h`` is conserved exactly
    when ``L`` does not depend explicitly on time, nothing dissipates, no
    generalized force acts and the constraints do not move.  It equals the
    total energy ``T + V`` for a scleronomic natural system; for a
    rheonomic one (a support moved at constant speed) it is the energy seen
    riding along, and ``T + V`` is not conserved.

    >>> import lagrangian as lg
    >>> m = lg.Model("oscillator")
    >>> _ = m.add("mass", "m", "p", m=2)
    >>> _ = m.add("spring", "k", ("ground", "p"), k=3)
    >>> h = jacobi_integral(m)
    >>> h.conserved, h.energy_conserved, h.expr
    (True, True, 3*x_p(t)**2/2 + Derivative(x_p(t), t)**2)
    """
    eq = model.eq
    generic = eq.generic()

    def integral() -> dict:  # on the generic energies, once per structure; the values go in after
        h = sp.Add(*[vi * pi for vi, pi in zip(eq.sym.v, generic["p"])]) - generic["L"]
        E = generic["T"] + generic["V"]
        if len(nodes([h])) > EXPAND_MAX:  # decided without multiplying out: h is shown as T + V where it is that
            if equal(h, E):
                return {"h": E, "E": E, "diff": sp.Integer(0)}
            return {"h": h, "E": E, "diff": sp.Add(h, sp.Mul(-1, E, evaluate=False), evaluate=False)}
        h = _tidy(sp.expand(h), 2000)
        if equal(h, E):
            return {"h": _without_residues(h, E), "E": E, "diff": sp.Integer(0)}
        return {"h": h, "E": E, "diff": _tidy(sp.expand(h - E), 2000)}

    parts = _by_structure(("jacobi", tuple(eq.sym.v), generic["L"], generic["T"], generic["V"]), eq.values, integral)
    h, E, diff = (_put(parts[k], eq.values) for k in ("h", "E", "diff"))
    reasons = []
    if _depends(eq, eq.L, t):
        moving = [name for name, c in model.assembly.contributions.items()
                  if any(_depends(eq, eq.symbolic(sp.sympify(getattr(c, part))), t) for part in ("T", "V", "G"))]
        reasons.append(f"L depends explicitly on time (through {_named(moving)})")
    if not is_zero(eq.D):
        reasons.append(f"energy dissipates (D from {_named([n for n, c in model.assembly.contributions.items() if sp.sympify(c.D) != 0])})")
    if any(not is_zero(e) for e in eq.Q):
        forced = [c for c, share in eq.load_shares if any(not is_zero(e) for e in share)]
        reasons.append(f"generalized forces act (from {_named(forced)})")
    if any(_depends(eq, c, t) for c in eq.constraints):
        reasons.append("a loop constraint moves with time")
    at_rest = {x: 0 for x in eq.sym.v}
    moving = sorted({o for o, c in zip(eq.velocity_owners, eq.velocity_constraints)
                     if _depends(eq, c, t) or not is_zero(c.xreplace(at_rest))})
    if moving:
        reasons.append(f"a constraint on velocities moves with time (from {_named(moving)}): its force does work")
    conserved = not reasons
    if conserved:
        reasons.append("L has no explicit time dependence and no dissipation, force or moving constraint acts")
    return JacobiIntegral(model, eq.display(h), eq.display(E), eq.display(diff), conserved, reasons)
