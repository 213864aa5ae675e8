"""Exact solution of large linear time-invariant models: the action of the matrix exponential on sparse matrices.

A model with thousands of coordinates (a chain of 10⁴ masses, a ladder of
2,000 sections) has a state-space matrix that is sparse, and whose
exponential is dense: 10⁴ coordinates make a 2·10⁴-square ``e^{F h}`` of
3.2 GB.  Its solution never needs that matrix, only its action on the state:
:func:`scipy.sparse.linalg.expm_multiply` (Al-Mohy and Higham's truncated
Taylor series with scaling, to double precision) computes ``e^{Z τ} z`` on a
uniform grid of ``τ`` with a few hundred sparse products, for the augmented
matrix ``Z = [[F, G C], [0, S]]`` of the state and the exosystem that
generates the inputs (see :mod:`lagrangian.numerics.linear`).

:class:`SparseSpace` is ``ẏ = F y + G s(t)`` built from the stamps of a model
(:mod:`lagrangian.derivation.stamps`): ``F`` explicit and sparse when the
matrix of the unknowns (masses, inductances, and the dampings of coordinates
without inertia) is diagonal, as for chains of masses and ladders of
inductors; otherwise an operator that solves with its sparse LU
factorization at each product.  Measured on a chain of 10,000 masses,
springs and dampers (``benchmarks/scale.py``): the states at 101 times over
1 s in 0.6 s, where the dense exponential does not fit in memory; on a
200-section RLC ladder over 30 s it agrees with the dense exact solution to
8e-14 of the peak.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import scipy.sparse as sps

from ..base import waveforms as _waveforms
from ..derivation.stamps import NotStampable, Stamps
from ..base.component import t
from .simulation import _lambdify

__all__ = ["KrylovPropagator", "SparseSpace", "dense_unknowns", "input_values", "unknowns"]


def unknowns(st: Stamps) -> tuple[sps.csc_matrix, sps.csr_matrix, sps.csr_matrix, sps.csr_matrix]:
    """``(A, R, Sel, E)`` of ``ẏ = Sel A⁻¹ (R y + B s) + E y``: ``A u = R y + B s`` for the unknowns
    ``u = (q̈_inertial, q̇_first_order)``, with ``R = [−K, −C_inertial]``; ``Sel`` puts ``u`` into the rates of
    the state ``y = (q, q̇_inertial)`` and ``E`` the inertial velocities into the rates of their coordinates."""
    import scipy.sparse as sps  # SciPy's sparse modules are imported by what uses them (0.2 s)

    n, I, Fo = st.n, st.inertial, st.first_order
    nI = len(I)
    ny = n + nI
    A = sps.hstack([st.M[:, I], st.C[:, Fo]]).tocsc()
    R = sps.hstack([-st.K, -st.C[:, I]]).tocsr()
    Sel = sps.csr_matrix((np.ones(n), (_selected(st), np.arange(n))), shape=(ny, n))
    E = sps.csr_matrix((np.ones(nI), (I, n + np.arange(nI))), shape=(ny, ny))
    return A, R, Sel, E


def dense_unknowns(st: Stamps) -> tuple[np.ndarray, ...]:
    """:func:`unknowns` and the stamps' ``B``, ``(A, R, B, Sel, E)``, as dense arrays: from a numeric assembly's
    dense matrices where the stamps have them (``NumericStamps.dense``: no ``scipy.sparse``), else from the
    stamps' sparse ones."""
    n, I, Fo = st.n, st.inertial, st.first_order
    nI = len(I)
    dense = getattr(st, "dense", None)
    M, C, K, B = (dense(w) if dense is not None else getattr(st, w).toarray() for w in "MCKB")
    Sel = np.zeros((n + nI, n))
    Sel[_selected(st), np.arange(n)] = 1.0
    E = np.zeros((n + nI, n + nI))
    E[I, n + np.arange(nI)] = 1.0
    return np.hstack([M[:, I], C[:, Fo]]), np.hstack([-K, -C[:, I]]), B, Sel, E


def _selected(st: Stamps) -> list[int]:
    """The rows of ``ẏ`` the unknowns ``u = (q̈_inertial, q̇_first_order)`` go to."""
    return [st.n + p for p in range(len(st.inertial))] + list(st.first_order)


@dataclass
class SparseSpace:
    """``ẏ = F y + G s(t)`` of a large model, ``F`` a sparse matrix or an operator (see the module documentation).

    It has the attributes of :class:`~lagrangian.numerics.linear.StateSpace` that the exact solution reads:
    ``states``, ``names``, ``inertial``, ``first_order``, ``inputs`` and ``equations``.
    """

    stamps: Stamps
    F: Any = None
    G: np.ndarray | None = None
    states: list[str] = field(default_factory=list)
    _pieces: dict = field(default_factory=dict, repr=False)
    _cuts: dict = field(default_factory=dict, repr=False)
    _input_fn: Any = field(default=None, repr=False)

    def __post_init__(self):
        import scipy.sparse as sps
        from scipy.sparse.linalg import LinearOperator, splu

        st = self.stamps
        n = st.n
        self.names = list(st.names)
        self.inertial = [st.names[i] for i in st.inertial]
        self.first_order = [st.names[i] for i in st.first_order]
        self.states = self.names + [f"{name}'" for name in self.inertial]
        self.inputs = list(st.inputs)
        self.equations = [st.names[r] for r in st.input_rows]
        A, R, Sel, E = unknowns(st)
        self._R, self._Sel, self._E = R, Sel, E
        off = A - sps.diags(A.diagonal())
        diagonal = A.shape[0] == A.shape[1] and off.count_nonzero() == 0 and np.all(A.diagonal() != 0)
        B = st.B.toarray()
        if diagonal:
            inv = sps.diags(1.0 / A.diagonal())
            self.F = (Sel @ inv @ R + E).tocsr()
            self.G = Sel @ (inv @ B)
            self._lu = None
        else:
            try:
                self._lu = lu = splu(A.tocsc())
            except RuntimeError as exc:  # exactly singular: the symbolic path says which coordinates
                raise NotStampable(f"the matrix of the unknowns is singular ({exc})") from None
            pivots = np.abs(lu.U.diagonal())
            if not pivots.min() > A.shape[0] * np.finfo(float).eps * pivots.max():  # numerically singular
                raise NotStampable("the matrix of the unknowns is singular to working precision")
            ny = R.shape[1]
            self.F = LinearOperator(
                (ny, ny), dtype=float,
                matvec=lambda y: Sel @ lu.solve(np.asarray(R @ y)) + E @ y,
                rmatvec=lambda x: R.T @ lu.solve(np.asarray(Sel.T @ x), trans="T") + E.T @ x,
            )
            self.G = Sel @ lu.solve(B) if B.shape[1] else np.zeros((ny, 0))
        self._n = n

    def velocities(self, Y: np.ndarray, S: np.ndarray | Callable[[], np.ndarray]) -> np.ndarray:
        """Velocities of all coordinates from states ``Y`` (``len(states) × N``) and inputs ``S`` (or what returns
        them)."""
        n = self._n
        S = S() if callable(S) else S
        if self._lu is None:
            out = self.F[:n] @ Y
            return out + self.G[:n] @ S if self.G.shape[1] else out
        rhs = self._R @ Y + (self.stamps.B @ S if S.shape[0] else 0)
        U = self._lu.solve(np.asarray(rhs))
        return (self._Sel @ U + self._E @ Y)[:n]

    def input_values(self, times: np.ndarray) -> np.ndarray:
        """The inputs ``s(t)`` at ``times``, as a ``len(inputs) × len(times)`` array."""
        return input_values(self, times)


def input_values(space, times: np.ndarray) -> np.ndarray:
    """The inputs ``space.inputs`` at ``times`` (``len(inputs) × len(times)``), compiled once per ``space``."""
    times = np.asarray(times, dtype=float)
    if not len(space.inputs):
        return np.zeros((0, times.size))
    if _waveforms.is_numeric(space.inputs):  # constants and waveforms: in numbers
        return _waveforms.values(list(space.inputs), times)
    if space._input_fn is None:
        space._input_fn = _lambdify(t, list(space.inputs), {})  # huge integers as floats, erf from SciPy
    with np.errstate(all="ignore"):
        values = space._input_fn(times)
    return np.array([np.broadcast_to(np.asarray(v, dtype=float), times.shape) for v in values])


class KrylovPropagator:
    """``e^{Z τ} z`` for ``Z = [[F, G C], [0, S]]`` (the state and the exosystem of one piece), by
    :func:`scipy.sparse.linalg.expm_multiply`."""

    def __init__(self, space: SparseSpace, S: np.ndarray | None = None, C: np.ndarray | None = None):
        import scipy.sparse as sps
        from scipy.sparse.linalg import LinearOperator

        self.ny = ny = space.F.shape[0]
        nw = 0 if S is None else S.shape[0]
        F = space.F
        if nw == 0:
            self.Z = F
        elif isinstance(F, LinearOperator):
            GC = space.G @ C
            self.Z = LinearOperator(
                (ny + nw, ny + nw), dtype=float,
                matvec=lambda z: np.concatenate([F @ z[:ny] + GC @ z[ny:], S @ z[ny:]]),
                rmatvec=lambda x: np.concatenate([F.rmatvec(x[:ny]), GC.T @ x[:ny] + S.T @ x[ny:]]),
            )
        else:
            self.Z = sps.bmat([[F, sps.csr_matrix(space.G @ C)], [None, sps.csr_matrix(S)]]).tocsr()
        self._trace = 0.0 if isinstance(self.Z, LinearOperator) else None

    def _expm(self, Zh, z, **grid):
        from scipy.sparse.linalg import expm_multiply

        with np.errstate(all="ignore"):  # an overflow shows as non-finite states, which the caller reports
            return expm_multiply(Zh, z, traceA=self._trace, **grid)

    def advance(self, z: np.ndarray, h: float) -> np.ndarray:
        """``e^{Z h} z``."""
        return z if h == 0 else self._expm(self.Z * h, z)

    def states(self, z: np.ndarray, start: float, times: np.ndarray, uniform: float | None) -> np.ndarray:
        """States at ``times`` (increasing, ≥ ``start``) from ``z`` at ``start``: one row per time."""
        out = np.empty((times.size, z.size))
        z = self.advance(z, float(times[0] - start))
        out[0] = z
        if times.size == 1:
            return out
        if uniform is not None:
            out[1:] = self._expm(self.Z, z, start=0.0, stop=float(times[-1] - times[0]), num=times.size,
                                 endpoint=True)[1:]
            return out
        for k in range(1, times.size):
            z = out[k] = self.advance(z, float(times[k] - times[k - 1]))
        return out
