"""The linearization about a steady motion and the verdict on its stability.

:class:`Perturbation` holds the linearized equations ``M s̈ + C ṡ + K s = 0``
about a steady motion, :class:`Stability` the verdict drawn from their
eigenvalues and the curvature of the effective potential; the helpers tidy a
linearization off the singular set of the reduction and format an eigenvalue.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...base.component import t
from ...base import display
from ...errors import ReductionError
from .tidy import _tidy
from ...base import deferred as _deferred

sp = _deferred.module("sympy", globals())


@dataclass
class Perturbation:
    """Linearized equations about a steady motion: ``M s̈ + C ṡ + K s = 0`` (``s = q − q₀``)."""

    M: sp.Matrix
    C: sp.Matrix
    K: sp.Matrix
    names: list[str]

    @property
    def equations(self) -> list[sp.Eq]:
        """One ``Eq(M s̈ + C ṡ + K s, 0)`` per remaining coordinate, in functions ``s_<name>(t)``."""
        s = sp.Matrix([sp.Function(f"s_{n}")(t) for n in self.names])
        lhs = self.M * s.diff(t, 2) + self.C * s.diff(t) + self.K * s
        return [sp.Eq(_tidy(e), 0) for e in lhs]

    @property
    def frequency_squared(self) -> sp.Expr:
        """One coordinate, no velocity terms: ``ω² = K / M`` of ``s̈ + ω² s = 0``."""
        if len(self.names) != 1 or self.C[0, 0] != 0:
            raise ReductionError("frequency_squared is defined for one coordinate without velocity terms; use eigenvalues.")
        return sp.simplify(self.K[0, 0] / self.M[0, 0])


@dataclass(repr=False)
class Stability:
    """The verdict on a steady motion from the linearized reduced equations, cross-checked with ``V_eff``."""

    verdict: str  # "stable", "asymptotically stable", "unstable" or "marginal"
    eigenvalues: np.ndarray
    frequencies: np.ndarray  # angular frequencies of the oscillatory modes (rad/s, ascending)
    curvature: np.ndarray | None  # eigenvalues of the Hessian of V_eff at the steady motion
    reason: str

    def __str__(self) -> str:
        return f"{self.verdict}: {self.reason}"

    def __repr__(self) -> str:
        return f"<Stability: {self.verdict}; eigenvalues {display.short([_fmt(z) for z in self.eigenvalues])}>"

    def _repr_html_(self) -> str:
        """The verdict, its reason, and the eigenvalues with the frequencies (Jupyter)."""
        rows = [["eigenvalues", display.short([_fmt(z) for z in self.eigenvalues], 12)],
                ["frequencies (rad/s)", display.short([f"{w:.6g}" for w in self.frequencies], 12) or "none"]]
        if self.curvature is not None:
            rows.append(["curvature of V_eff", display.short([f"{c:.6g}" for c in self.curvature], 12)])
        return display.block(self.verdict, f"<p>{display.escape(self.reason)}</p>", display.table(["", ""], rows))


def _off_singular(expr: sp.Expr) -> sp.Expr:
    """Tidy a linearization evaluated at a steady motion, which lies off the singular set of the
    reduction: there ``DiracDelta`` (from differentiating ``|x|`` twice) vanishes and
    ``sign(x)`` of a nonnegative ``x`` is 1."""
    expr = sp.sympify(expr).replace(sp.DiracDelta, lambda *a: sp.Integer(0))
    expr = expr.replace(lambda e: isinstance(e, sp.sign) and e.args[0].is_nonnegative, lambda e: sp.Integer(1))
    return _tidy(expr)


def _fmt(z: complex) -> str:
    return f"{z.real:.6g}{z.imag:+.6g}j" if abs(z.imag) > 0 else f"{z.real:.6g}"
