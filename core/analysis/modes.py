"""Natural modes of a linearized model, and the eigenvalue problems poles and zeros come from.

The Laplace form of a linearization (:mod:`lagrangian.analysis.linearize`)
is written as a descriptor pencil ``A − σE`` (:func:`_descriptor`), in
``σ = s / w0`` with ``w0`` a characteristic rate of the model, so that
circuits at MHz and mechanisms at Hz are both well scaled; its finite
generalized eigenvalues are the poles, those of the Rosenbrock system
matrix the invariant zeros.  :func:`modes` gives natural frequencies,
damping ratios and mode shapes: from the symmetric problem
``K φ = ω² M φ`` for an undamped model without constraints, from the
pencil otherwise.

>>> import lagrangian as lg
>>> from lagrangian.frequency import modes
>>> m = lg.Model("lc")
>>> _ = m.add("inductor", "L1", ("a", "0"), L=7e-3)
>>> _ = m.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
>>> round(float(modes(m).frequencies[0]), 3)     # 1 / (2π √(LC)) Hz
1282.507
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..base import charts, display

from ..errors import ModelError
from ..model import Model
from .linearize import LinearModel, linearize

__all__ = ["Modes", "modes"]

#: An eigenvalue of the scaled pencil with ``|β| ≤ INFINITE·|α|`` is infinite (an algebraic constraint).
INFINITE = 1e-11


def _linear(system: Model | LinearModel, inputs, outputs, kwargs) -> LinearModel:
    if isinstance(system, LinearModel):
        if kwargs:
            raise ModelError(f"{', '.join(kwargs)} apply when linearizing a model; this is already linear.")
        return system
    return linearize(system, inputs=inputs, outputs=outputs, **kwargs)


def _balance(lin: LinearModel) -> tuple[LinearModel, np.ndarray]:
    """``lin`` in coordinates scaled by ``d`` (``q = d·q̃``), each coordinate's own stiffness (or, without one, its
    damping or inertia at the model's rate) made 1; and ``d``.  Eigenvalues and zeros do not change; the pencil's
    entries do, from spanning the decades between an electrical and a mechanical coordinate (a capacitor's 1/C of
    10⁷ beside a spring of 1) to a few: without it QZ, backward stable in the pencil's norm, loses the small
    stiffness."""
    w = _rate(lin)
    size = np.maximum.reduce([np.abs(np.diag(lin.K)), np.abs(np.diag(lin.C)) * w, np.abs(np.diag(lin.M)) * w**2])
    d = np.where(size > 0, 1 / np.sqrt(np.where(size > 0, size, 1.0)), 1.0)
    D = np.diag(d)
    scaled = LinearModel(**{**lin.__dict__, "M": D @ lin.M @ D, "C": D @ lin.C @ D, "K": D @ lin.K @ D,
                            "Phi": lin.Phi @ D, "Phi_v": None if lin.Phi_v is None else lin.Phi_v @ D,
                            "B": [D @ b for b in lin.B], "Bi": D @ lin.Bi,
                            "Cq": [c @ D for c in lin.Cq]})
    return scaled, d


#: An eigenvalue within this share of the largest (:attr:`Modes.scale`) counts as zero: a rigid-body mode.  The
#: symmetric solve's ``ω`` errs by about ``√ε`` (1.5e-8) of the largest near zero (``ω²`` errs by ``ε`` of the
#: largest); measured: two free masses' zero mode came out at 9e-9 of the other.  A true mode this slow would be
#: known to a few per cent only.
RIGID = 1e-7


def _scale(lin: LinearModel) -> float:
    """A characteristic rate of the system (rad/s), to scale ``s`` by before eigenvalue problems (of the balanced
    system, :func:`_balance`)."""
    return _rate(_balance(lin)[0])


def _rate(lin: LinearModel) -> float:
    norms = [float(np.linalg.norm(x)) for x in (lin.M, lin.C, lin.K)]
    nM, nC, nK = norms
    if nM and nK:
        return math.sqrt(nK / nM)
    if nC and nK:
        return nK / nC
    if nM and nC:
        return nC / nM
    return 1.0


def _numeric(lin: LinearModel, what: str) -> None:
    if lin.symbolic:
        raise ModelError(f"{what} of model {lin.model!r} needs numbers for its parameters "
                         f"({', '.join(p.name for p in lin.parameters)}): give them in params=.")


def _descriptor(lin: LinearModel, with_io: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(A, E)`` of a descriptor realization of ``lin``, its pencil ``A − σE`` in ``σ = s / w0``
    (:func:`_scale`); ``with_io``: the Rosenbrock system matrix of its single input and output, whose finite
    eigenvalues are the invariant zeros.

    Unknowns ``(q, v, a, λ)``, with ``v`` and ``a`` scaled by ``w0`` and ``w0²``: ``σ q = ṽ``, ``σ ṽ = ã``,
    ``0 = −M w0² ã − C w0 ṽ − K q + Wᵀλ + Σ b_k w_k``, ``0 = Φ q + Φ_v w0 ṽ`` (``W`` the directions of the
    constraints' forces, ``Φ_v`` the coefficient of ``s`` of those on velocities).  With the input: a chain ``w_k = s^k u``
    (or ``s^(k−1) u`` when the input's integral enters, ``Bi`` or ``Di``), scaled by ``w0^k``, rows ``σ w_k = w_(k+1)``,
    ``u = w_0`` (or ``u = s w_0``), and the output row ``y = 0``."""
    lin, _ = _balance(lin)
    w0 = _rate(lin)
    n, m = len(lin.coordinates), lin.Phi.shape[0]
    integral = with_io and bool(np.any(lin.Bi) or np.any(lin.Di))
    coeffs = ([lin.Bi] if integral else []) + list(lin.B)
    outs = ([lin.Di] if integral else []) + list(lin.D)
    order = max(len(coeffs), len(outs)) - 1
    iq, iv, ia, il, iw = 0, n, 2 * n, 3 * n, 3 * n + m
    N = iw + (order + 2 if with_io else 0)
    A, E = np.zeros((N, N)), np.zeros((N, N))
    eye = np.eye(n)
    E[iq:iv, iq:iv] = eye
    A[iq:iv, iv:ia] = eye
    E[iv:ia, iv:ia] = eye
    A[iv:ia, ia:il] = eye
    A[ia:il, iq:iv] = -lin.K
    A[ia:il, iv:ia] = -lin.C * w0
    A[ia:il, ia:il] = -lin.M * w0**2
    A[ia:il, il:iw] = lin.force_rows().T
    A[il:iw, iq:iv] = lin.Phi
    if lin.velocity_rows:  # (∂c/∂q + A s) q = 0: s q = w0 ṽ
        A[il:iw, iv:ia] = lin.rate_rows() * w0
    if not with_io:
        return A, E
    iu, row_in, row_out = iw + order + 1, iw + order, iw + order + 1
    for k, b in enumerate(coeffs):
        A[ia:il, iw + k] = b[:, 0] * w0**k
    for k in range(order):
        E[iw + k, iw + k] = 1
        A[iw + k, iw + k + 1] = 1
    A[row_in, iu] = 1
    if integral:
        E[row_in, iw] = w0  # u − s w_0 = 0
    else:
        A[row_in, iw] = -1  # u − w_0 = 0
    Cq = list(lin.Cq) + [np.zeros_like(lin.Cq[0])] * (3 - len(lin.Cq))
    A[row_out, iq:iv] = Cq[0][0]
    A[row_out, iv:ia] = Cq[1][0] * w0
    A[row_out, ia:il] = Cq[2][0] * w0**2
    for k, d in enumerate(outs):  # D_k s^k u = D_k w_(k+shift)
        A[row_out, iw + k] += d[0, 0] * w0**k
    return A, E


def _eigenvalues(pencil: tuple[np.ndarray, np.ndarray], w0: float) -> np.ndarray:
    import scipy.linalg

    A, E = pencil
    if not A.size:
        return np.zeros(0, dtype=complex)
    ab = scipy.linalg.eigvals(A, E, homogeneous_eigvals=True)
    alpha, beta = ab[0], ab[1]
    finite = np.abs(beta) > INFINITE * np.abs(alpha)
    lam = alpha[finite] / beta[finite] * w0
    lam = np.where(np.abs(lam.imag) <= 1e-12 * np.abs(lam), lam.real + 0j, lam)
    return lam[np.lexsort((lam.imag, np.abs(lam)))]


@dataclass
class Modes:
    """Natural modes of a linearized model, slowest first.

    ``eigenvalues`` (rad/s, one per mode: the one with non-negative
    imaginary part of a complex pair), ``omega`` the natural angular
    frequencies ``|λ|``, ``frequencies`` the same in Hz, ``damping`` the
    damping ratios ``−Re λ / |λ|``, ``shapes`` the mode shapes (coordinates ×
    modes; real for an undamped model, normalized so that the largest
    entry is 1).
    """

    model: str
    coordinates: list[str]
    eigenvalues: np.ndarray
    shapes: np.ndarray
    method: str = ""
    #: the system's rate scale (rad/s) against which an eigenvalue counts as zero (:attr:`kinds`)
    scale: float = 0.0

    @property
    def omega(self) -> np.ndarray:
        return np.abs(self.eigenvalues)

    @property
    def kinds(self) -> list[str]:
        """Per mode: ``"rigid"`` (an eigenvalue zero within rounding: a free coordinate, a rigid-body motion, a free
        integrator), ``"real"`` (a real eigenvalue: an exponential decay, or growth, with no oscillation) or
        ``"oscillatory"``.  Zero within rounding: ``|λ| ≤`` :data:`RIGID` times :attr:`scale` (an eigenvalue
        of ``K φ = ω² M φ`` errs by about ``√ε`` of the largest, as ``ω²`` errs by ``ε`` of it)."""
        return [self._kind(lam) for lam in self.eigenvalues]

    def _kind(self, lam: complex) -> str:
        tol = RIGID * self.scale
        return "rigid" if abs(lam) <= tol else "real" if abs(lam.imag) <= tol else "oscillatory"

    def describe(self, j: int) -> str:
        """Mode ``j`` in words: ``"2.906 Hz (ζ=0.01)"``, ``"rigid (λ = 0)"``, ``"real: decays by e in 0.6 s"``."""
        lam = self.eigenvalues[j]
        kind = self._kind(lam)
        if kind == "rigid":
            return "rigid (λ = 0)"
        if kind == "real":
            return f"real: {'decays' if lam.real < 0 else 'grows'} by e in {1 / abs(lam.real):.4g} s"
        return f"{self.frequencies[j]:.4g} Hz (ζ={self.damping[j]:.3g})"

    @property
    def frequencies(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    @property
    def damping(self) -> np.ndarray:
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.omega > 0, -self.eigenvalues.real / np.where(self.omega > 0, self.omega, 1), 1.0) + 0.0

    def __repr__(self) -> str:
        rows = ", ".join(self.describe(j) for j in range(min(6, len(self.eigenvalues))))
        more = f", … {len(self.eigenvalues)} in all" if len(self.eigenvalues) > 6 else ""
        return f"<Modes of {self.model!r}: {rows}{more}>"

    def _repr_html_(self) -> str:
        """A table of the modes: kind, frequency, damping ratio and eigenvalue (Jupyter)."""
        rows = [[j + 1, kind, f"{f:.6g}" if kind == "oscillatory" else "", f"{z:.4g}" if kind == "oscillatory" else "",
                 f"{lam:.6g}"] for j, (kind, f, z, lam) in enumerate(zip(self.kinds, self.frequencies, self.damping,
                                                                          self.eigenvalues))]
        return display.block(f"modes of {self.model}", display.table(
            ["mode", "kind", "frequency (Hz)", "damping ratio ζ", "eigenvalue λ (1/s)"], rows), note=self.method)

    @charts.plain
    def plot(self, count: int | None = None, path: str | None = None):
        """Mode shapes against coordinate index (a chain's modes as standing waves); returns the Figure."""
        k = min(count or 4, len(self.eigenvalues))
        fig, ax = charts.subplots(figsize=(7, 4))
        x = np.arange(len(self.coordinates))
        for j in range(k):
            ax.plot(x, self.shapes[:, j].real, "o-", label=self.describe(j))
        ax.axhline(0, color="k", lw=0.5)
        if len(x) <= 12:
            ax.set_xticks(x, self.coordinates, rotation=45, ha="right")
        else:
            ax.set_xlabel("coordinate index")
        ax.set_ylabel("mode shape (largest entry 1)")
        ax.set_title(f"{self.model}: normal modes")
        ax.legend(fontsize=8)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def modes(system: Model | LinearModel, **kwargs: Any) -> Modes:
    """Natural frequencies, damping ratios and mode shapes of ``system`` linearized (``kwargs`` as for
    :func:`linearize`).  An undamped model without constraints or first-order coordinates is solved as the
    symmetric problem ``K φ = ω² M φ``; any other from the pencil of its Laplace form."""
    import scipy.linalg

    lin = _linear(system, [], None, kwargs) if isinstance(system, Model) else system
    _numeric(lin, "modes")
    n = len(lin.coordinates)
    symmetric = (not lin.Phi.shape[0] and not lin.first_order and not np.any(lin.C)
                 and np.allclose(lin.M, lin.M.T, rtol=1e-12, atol=0) and np.allclose(lin.K, lin.K.T, rtol=1e-12, atol=0))
    if symmetric:
        try:
            w2, phi = scipy.linalg.eigh(lin.K, lin.M)
        except np.linalg.LinAlgError:
            symmetric = False
    if symmetric:
        lam = np.sqrt(w2.astype(complex)) * 1j  # ω² < 0 (unstable) gives a real positive λ
        lam = np.where(w2 < 0, np.sqrt(np.abs(w2)) + 0j, lam)
        shapes = phi.astype(complex)
        method = "symmetric K φ = ω² M φ"
    else:
        w0 = _scale(lin)
        A, E = _descriptor(lin, with_io=False)
        alpha, beta, vecs = _eig_vectors(A, E)
        finite = np.abs(beta) > INFINITE * np.abs(alpha)
        lam = alpha[finite] / beta[finite] * w0
        shapes = vecs[:n, finite] * _balance(lin)[1][:, None]  # back from the balanced coordinates
        keep = lam.imag >= -1e-12 * np.abs(lam)
        lam, shapes = lam[keep], shapes[:, keep]
        method = "generalized eigenvalues of the Laplace-form pencil"
    order = np.lexsort((lam.imag, np.abs(lam)))
    lam, shapes = lam[order], shapes[:, order]
    for j in range(shapes.shape[1]):
        col = shapes[:, j]
        big = col[np.argmax(np.abs(col))] if len(col) else 1
        shapes[:, j] = col / big if big else col
    if symmetric:
        shapes = shapes.real
    scale = float(np.max(np.abs(lam), initial=0.0)) or _rate(lin)
    return Modes(lin.model, list(lin.coordinates), lam, shapes, method, scale)


def _eig_vectors(A: np.ndarray, E: np.ndarray):
    import scipy.linalg

    ab, vecs = scipy.linalg.eig(A, E, homogeneous_eigvals=True)
    return ab[0], ab[1], vecs
