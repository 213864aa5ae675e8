"""A model's frequency response as a function of chosen parameters, with its exact derivatives by them.

:class:`ParametricResponse` linearizes a model once with the chosen parameters (by their
:attr:`~lagrangian.Model.parameter_values` names) as symbols (:func:`~lagrangian.frequency.linearize`),
differentiates the Laplace-form matrices by each symbolically, and turns both into NumPy functions.  At any values
``θ`` it gives ``H(s)`` of every output to every input and ``∂H/∂θ_j``: with ``P(s) X = R(s)`` the Laplace-form
system (constraint rows included) and ``H = C(s) X + D(s)``,

    ∂X/∂θ = P⁻¹ (∂R/∂θ − (∂P/∂θ) X),      ∂H/∂θ = (∂C/∂θ) X + C ∂X/∂θ + ∂D/∂θ,

one factorization per frequency serving every derivative.  It serves
:func:`~lagrangian.frequency.frequency_response`'s ``sensitivities=`` and :func:`lagrangian.fit`.

>>> import numpy as np, lagrangian as lg
>>> m = lg.Model("rc")
>>> _ = m.add("voltage_source", "V1", ("a", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("a", "b"), R=1e3)
>>> _ = m.add("capacitor", "C1", ("b", "0"), C=1e-6)
>>> p = ParametricResponse(m, ["V1"], ["i(R1)"], ["R_R1"])
>>> H, dH = p.evaluate([1e3], np.array([159.15494309189535]))  # ω = 1/(RC): H = jωC / (1 + jωRC)
>>> bool(np.isclose(H[0, 0, 0], 1j * 1e-3 / (1 + 1j))), bool(np.isclose(dH[0, 0, 0, 0], -(1j * 1e-3)**2 / (1 + 1j)**2))
(True, True)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import NumericalError
from .linearize import linearize
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

__all__ = ["ParametricResponse", "COEFFICIENTS_MAX"]

#: Largest system (coordinates and constraints) whose transfer function :meth:`ParametricResponse.coefficients`
#: forms symbolically.
COEFFICIENTS_MAX = 6


class ParametricResponse:
    """``H(j2πf; θ)`` of ``outputs`` to ``inputs`` of ``model`` and its derivatives by the parameters ``names``
    (see the module's text)."""

    def __init__(self, model: Any, inputs: Sequence[str] | None, outputs: Sequence[Any] | None, names: Sequence[str]):
        self.names = list(names)
        symbols = [sp.Symbol(f"theta{i}", real=True) for i in range(len(self.names))]
        lin = linearize(model, inputs=inputs, outputs=outputs, params=dict(zip(self.names, symbols)), symbolic=True)
        self.inputs, self.outputs = list(lin.inputs), list(lin.outputs)
        parts = {"M": lin.M, "C": lin.C, "K": lin.K, "Phi": lin.Phi, "rate": lin.rate_rows(), "force": lin.force_rows(),
                 "Bi": lin.Bi, "Di": lin.Di}
        parts.update({f"B{k}": b for k, b in enumerate(lin.B)})
        parts.update({f"Cq{k}": c for k, c in enumerate(lin.Cq)})
        parts.update({f"D{k}": d for k, d in enumerate(lin.D)})
        self._sizes = (len(lin.coordinates), lin.Phi.shape[0], len(lin.B), len(lin.Cq), len(lin.D))
        flat = {key: sp.Matrix(value) for key, value in parts.items()}
        self._value = {k: sp.lambdify([symbols], v, "numpy") for k, v in flat.items()}
        self._slope = [{k: sp.lambdify([symbols], v.diff(s), "numpy") for k, v in flat.items() if v.has(s)}
                       for s in symbols]
        self._shapes = {k: v.shape for k, v in flat.items()}
        self._flat, self._symbols = flat, symbols

    def coefficients(self, output: int = 0, input: int = 0) -> tuple[list[sp.Expr], list[sp.Symbol]] | None:
        """The coefficients of ``H[output, input](s)`` as a ratio of polynomials in ``s`` with a monic denominator
        (its highest power's coefficient 1), as expressions of the parameters' symbols (and the symbols); ``None``
        when the system has more than :data:`COEFFICIENTS_MAX` unknowns (its symbolic inverse would not pay).  What
        a measured response determines — with exact data at every frequency — is these coefficients and no more."""
        n, m, nb, nc, nd = self._sizes
        if n + m > COEFFICIENTS_MAX:
            return None
        s = sp.Symbol("s")
        f = self._flat
        P = sp.zeros(n + m, n + m)
        P[:n, :n] = (f["M"] * s + f["C"]) * s + f["K"]
        if m:
            P[:n, n:] = -f["force"].T
            P[n:, :n] = f["Phi"] + f["rate"] * s
        R = sp.zeros(n + m, 1)
        R[:n, 0] = sum((f[f"B{k}"][:, input] * s**k for k in range(nb)), sp.zeros(n, 1)) + f["Bi"][:, input] / s
        C = sp.zeros(1, n + m)
        C[0, :n] = sum((f[f"Cq{k}"][output, :] * s**k for k in range(nc)), sp.zeros(1, n))
        D = sum((f[f"D{k}"][output, input] * s**k for k in range(nd)), sp.Integer(0)) + f["Di"][output, input] / s
        H = sp.together(sp.cancel((C * P.LUsolve(R))[0, 0] + D))
        top, bottom = (sp.Poly(sp.expand(e), s) for e in sp.fraction(H))
        lead = bottom.LC()
        return [sp.cancel(c / lead) for c in top.all_coeffs() + bottom.all_coeffs()[1:]], self._symbols

    def _parts(self, functions: dict, theta: np.ndarray) -> dict[str, np.ndarray]:
        out = {k: np.zeros(shape) for k, shape in self._shapes.items()}
        out.update({k: np.asarray(f(theta), dtype=float).reshape(self._shapes[k]) for k, f in functions.items()})
        return out

    def _system(self, parts: dict, s: np.ndarray):
        """``(P, R, C, D)`` stacked over ``s``: ``P X = R`` (unknowns × inputs), ``H = C X + D``."""
        n, m, nb, nc, nd = self._sizes
        sv = s[:, None, None]
        P = np.zeros((s.size, n + m, n + m), dtype=complex)
        P[:, :n, :n] = (parts["M"] * sv + parts["C"]) * sv + parts["K"]
        if m:
            P[:, :n, n:] = -parts["force"].T
            P[:, n:, :n] = parts["Phi"] + parts["rate"] * sv
        R = np.zeros((s.size, n + m, len(self.inputs)), dtype=complex)
        R[:, :n] = sum(parts[f"B{k}"] * sv**k for k in range(nb)) + parts["Bi"] / sv
        C = np.zeros((s.size, len(self.outputs), n + m), dtype=complex)
        C[:, :, :n] = sum(parts[f"Cq{k}"] * sv**k for k in range(nc))
        D = sum((parts[f"D{k}"] * sv**k for k in range(nd)), np.zeros((s.size,) + self._shapes["Di"], complex))
        return P, R, C, D + parts["Di"] / sv

    def evaluate(self, theta: Sequence[float], frequencies: np.ndarray, jacobian: bool = True):
        """``H`` (outputs × inputs × frequencies) at ``θ`` and, with ``jacobian``, ``∂H/∂θ`` (parameters × outputs
        × inputs × frequencies; else ``None``).  Frequencies in Hz, positive."""
        theta = np.asarray(theta, dtype=float)
        s = 2j * np.pi * np.asarray(frequencies, dtype=float)
        P, R, C, D = self._system(self._parts(self._value, theta), s)
        try:
            X = np.linalg.solve(P, R)
        except np.linalg.LinAlgError:
            raise NumericalError(f"the response is singular at {dict(zip(self.names, theta.tolist()))} on this "
                                 f"frequency grid (a pole on it).") from None
        H = np.moveaxis(C @ X + D, 0, -1)
        if not jacobian:
            return H, None
        dH = np.empty((len(self.names),) + H.shape, dtype=complex)
        for j, slope in enumerate(self._slope):
            dP, dR, dC, dD = self._system(self._parts(slope, theta), s)
            dX = np.linalg.solve(P, dR - dP @ X)
            dH[j] = np.moveaxis(dC @ X + C @ dX + dD, 0, -1)
        return H, dH
