"""Equations of motion from the Lagrangian, in mass-matrix form.

For ``L = T - V + G`` (``G``: velocity-linear couplings that store no
energy), Rayleigh function ``D`` and generalized forces ``Q``:

    d/dt ∂L/∂q̇ - ∂L/∂q + ∂D/∂q̇ = Q

is written ``M(q, t) q̈ = f(q, q̇, t)`` with

    p = ∂L/∂q̇,   M = ∂p/∂q̇,   f = ∂L/∂q - (∂p/∂q) q̇ - ∂p/∂t - ∂D/∂q̇ + Q,

derived on plain symbols standing for ``q`` and ``q̇`` (no time
differentiation of functions, no global ``simplify``).

Coordinates with no inertia at all (a zero row of ``M``: a node with no
mass, a loop with no inductor) but with dissipation are first-order: their
velocities are unknowns of the same linear solve as the accelerations of the
others.  The solve is ``A u = b`` with ``u = (q̈_inertial, q̇_first_order)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .assembly import Assembly
from .component import t
from .errors import ModelError

__all__ = ["Equations"]


def _is_zero(expr: sp.Expr) -> bool:
    return expr == 0 or sp.expand(expr) == 0


@dataclass
class _Symbols:
    q: list[sp.Symbol]
    v: list[sp.Symbol]
    a: list[sp.Symbol]


class Equations:
    """Mass matrix, forcing and the first-order solve of an :class:`~lagrangian.assembly.Assembly`."""

    def __init__(self, assembly: Assembly):
        if not assembly.coordinates:
            raise ModelError(
                "the model has no generalized coordinates: every node is fixed by ideal sources or prescribed "
                "motions, so there is nothing to solve for. Add an element that can move (a mass, a capacitor "
                "between free nodes), or use the other circuit formulation."
            )
        self.coordinates = assembly.coordinates
        names = [c.name for c in self.coordinates]
        self.names = names
        self.sym = _Symbols(
            [sp.Symbol(f"q_{n}", real=True) for n in names],
            [sp.Symbol(f"v_{n}", real=True) for n in names],
            [sp.Symbol(f"a_{n}", real=True) for n in names],
        )
        funcs = [c.function for c in self.coordinates]
        self._to_sym = {}
        for f, q, v in zip(funcs, self.sym.q, self.sym.v):
            self._to_sym[f.diff(t, 2)] = sp.Symbol(f"_acc_{f.func}")  # never allowed, caught below
            self._to_sym[f.diff(t)] = v
            self._to_sym[f] = q
        self._from_sym = {}
        for f, q, v, a in zip(funcs, self.sym.q, self.sym.v, self.sym.a):
            self._from_sym.update({q: f, v: f.diff(t), a: f.diff(t, 2)})

        q, v = self.sym.q, self.sym.v
        self.T = self.symbolic(assembly.T)
        self.V = self.symbolic(assembly.V)
        self.D = self.symbolic(assembly.D)
        self.G = self.symbolic(assembly.G)
        self.L = self.T - self.V + self.G
        Q = [sp.Integer(0)] * len(q)
        for name, load in assembly.loads:
            force = sp.Matrix([load.force]) if not isinstance(load.force, sp.MatrixBase) else load.force
            vel = sp.Matrix([load.velocity]) if not isinstance(load.velocity, sp.MatrixBase) else load.velocity
            if force.shape != vel.shape:
                raise ModelError(f"component {name!r}: a load's force {force.shape} and velocity {vel.shape} differ in shape.")
            force, vel = force.applyfunc(self.symbolic), vel.applyfunc(self.symbolic)
            for i, vi in enumerate(v):
                partial = vel.diff(vi)
                if any(not _is_zero(e) for e in partial):
                    Q[i] += (force.T * partial)[0, 0]
        self.Q = sp.Matrix(Q)
        p = [sp.diff(self.L, vi) for vi in v]
        self.p = sp.Matrix(p)
        n = len(q)
        self.M = sp.Matrix(n, n, lambda i, j: sp.diff(p[i], v[j]))
        self.f = sp.Matrix(
            [
                sp.diff(self.L, q[i])
                - sum((sp.diff(p[i], q[j]) * v[j] for j in range(n)), sp.Integer(0))
                - sp.diff(p[i], t)
                - sp.diff(self.D, v[i])
                + Q[i]
                for i in range(n)
            ]
        )
        self.constraints = sp.Matrix([self.symbolic(c) for view in assembly.views.values() for c in view.constraints])
        self.constraint_rate = max((getattr(v, "constraint_rate", 10.0) for v in assembly.views.values()), default=10.0)
        self.multipliers = [sp.Symbol(f"lambda_{k}", real=True) for k in range(len(self.constraints))]
        self._split()

    def symbolic(self, expr) -> sp.Expr:
        """Rewrite an expression in ``q(t)``, ``q̇(t)`` as one in the plain symbols used internally."""
        out = sp.sympify(expr).xreplace(self._to_sym)
        bad = [s for s in out.free_symbols if s.name.startswith("_acc_")]
        if bad:
            raise ModelError(f"an energy term depends on an acceleration ({bad[0].name[5:]}''); energies may use only q and q'.")
        return out

    def display(self, expr):
        """Rewrite an internal expression back in terms of ``q(t)`` and its derivatives."""
        return expr.xreplace(self._from_sym) if hasattr(expr, "xreplace") else expr

    def _split(self) -> None:
        n = len(self.names)
        M = self.M
        zero_rows = [i for i in range(n) if all(_is_zero(M[i, j]) for j in range(n))]
        self.inertial = [i for i in range(n) if i not in zero_rows]
        self.first_order = zero_rows
        unknowns = [self.sym.a[i] for i in self.inertial] + [self.sym.v[i] for i in self.first_order]
        residual = sp.Matrix([sum((M[i, j] * self.sym.a[j] for j in self.inertial), sp.Integer(0)) - self.f[i] for i in range(n)])
        if len(self.constraints):
            residual, unknowns = self._constrained(residual, unknowns)
        A = residual.jacobian(unknowns)
        if A.free_symbols & set(unknowns):
            culprit = sorted((s.name[2:] for s in A.free_symbols & set(unknowns)))
            raise ModelError(
                f"the equations are nonlinear in the velocity of first-order coordinate(s) {', '.join(culprit)}; "
                f"give those coordinates inertia (a mass, an inductor, a capacitor)."
            )
        for col, i in enumerate(self.first_order, start=len(self.inertial)):
            if all(_is_zero(A[r, col]) for r in range(n)):
                raise ModelError(
                    f"coordinate {self.names[i]!r} has neither inertia nor dissipation, so nothing determines its motion "
                    f"(a node with only springs, or a loop with only capacitors and sources). Add a mass or damper "
                    f"(an inductor or resistor), or remove the node."
                )
        self.A = A
        self.b = -residual.xreplace({u: sp.Integer(0) for u in unknowns})

    def _constrained(self, residual: sp.Matrix, unknowns: list) -> tuple[sp.Matrix, list]:
        """Append multipliers and the stabilized constraint rows ``Φ̈ + 2ωΦ̇ + ω²Φ = 0`` (Baumgarte)."""
        q, v, a = self.sym.q, self.sym.v, self.sym.a
        Phi = self.constraints
        Jq = Phi.jacobian(q)
        involved = [self.names[i] for i in self.first_order if any(not _is_zero(Jq[k, i]) for k in range(Jq.rows))]
        if involved:
            raise ModelError(
                f"coordinates {', '.join(involved)} have no inertia but take part in a loop-closure constraint: give them mass."
            )
        Phi_dot = Jq * sp.Matrix(v) + Phi.diff(t)
        w = sp.Float(self.constraint_rate)
        rows = Jq * sp.Matrix(a) + Phi_dot.jacobian(q) * sp.Matrix(v) + Phi_dot.diff(t) + 2 * w * Phi_dot + w**2 * Phi
        residual = residual - Jq.T * sp.Matrix(self.multipliers)
        return residual.col_join(rows), unknowns + self.multipliers

    # -- display helpers -------------------------------------------------------
    @property
    def mass_matrix(self) -> sp.Matrix:
        return self.M.applyfunc(self.display)

    @property
    def forcing(self) -> sp.Matrix:
        return self.f.applyfunc(self.display)

    def as_equalities(self) -> list[sp.Eq]:
        """One ``Eq(Σ_j M_ij q̈_j, f_i)`` per coordinate, in terms of ``q(t)``."""
        lhs = self.M * sp.Matrix(self.sym.a)
        return [sp.Eq(self.display(l), self.display(r)) for l, r in zip(lhs, self.f)]
