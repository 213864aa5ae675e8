"""The frequency domain: transfer functions, impedances, frequency response and normal modes.

Everything here works on the linearization of a model about an operating
point (:func:`linearize`, in :mod:`lagrangian.analysis.linearize`), in
Laplace form: ``H(s) = (Σ Cq_k s^k) X(s) + Σ D_k s^k`` with ``X`` solving
``[[M s² + C s + K, −Φ_qᵀ], [Φ_q, 0]] X = [Σ B_k s^k; 0]``.  Loop
constraints stay exact, inputs may enter through their derivatives (a
prescribed motion through a damper), and nothing is inverted that need not
be.

- :func:`transfer_function`: ``H(s)`` between one input and one output, as a
  SymPy rational function (exact in the parameters' symbols for a symbolic
  model), with its poles, zeros and DC gain;
- :func:`impedance`: the driving-point impedance seen by a source;
- :func:`frequency_response`: ``H(j 2π f)`` for every input and output on a
  frequency grid (:func:`decades` makes SPICE's ``.ac dec`` grid), with Bode
  and Nyquist charts;
- :func:`modes`: natural frequencies, damping ratios and mode shapes.

A series RLC driven by a voltage source: its current over the source
voltage is ``s C / (L C s² + R C s + 1)``.

>>> import sympy as sp
>>> import lagrangian as lg
>>> from lagrangian.frequency import transfer_function, modes
>>> m = lg.Model("rlc")
>>> _ = m.add("voltage_source", "V1", ("in", "0"), E=0)
>>> _ = m.add("resistor", "R1", ("in", "a"), R=sp.Symbol("R", positive=True))
>>> _ = m.add("inductor", "L1", ("a", "b"), L=sp.Symbol("L", positive=True))
>>> _ = m.add("capacitor", "C1", ("b", "0"), C=sp.Symbol("C", positive=True))
>>> H = transfer_function(m, "V1", "i(L1)")
>>> H.expr
C*s/(C*L*s**2 + C*R*s + 1)
>>> m2 = lg.Model("lc")
>>> _ = m2.add("inductor", "L1", ("a", "0"), L=7e-3)
>>> _ = m2.add("capacitor", "C1", ("a", "0"), C=2.2e-6)
>>> round(float(modes(m2).frequencies[0]), 3)     # 1 / (2π √(LC)) Hz
1282.507
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp

from ..errors import ModelError, UnknownNameError
from ..model import Model
from .linearize import LinearModel, linearize, s
from .modes import Modes, _descriptor, _eigenvalues, _linear, _numeric, _scale, modes

__all__ = ["FrequencyResponse", "Modes", "TransferFunction", "decades", "frequency_response", "impedance",
           "linearize", "modes", "s", "sweep", "transfer_function"]

#: Largest number of unknowns for which a transfer function is solved in exact arithmetic with SymPy.
SYMBOLIC_MAX = 8


def decades(start: float, stop: float, points: int = 20) -> np.ndarray:
    """Frequencies from ``start`` to ``stop`` (Hz), ``points`` per decade, as ngspice's ``.ac dec`` makes them
    (:func:`sweep`).

    >>> decades(1, 100, 2).round(3).tolist()
    [1.0, 3.162, 10.0, 31.623, 100.0]
    """
    return sweep("dec", points, start, stop)


def sweep(kind: str, points: int, start: float, stop: float) -> np.ndarray:
    """The frequencies of ngspice's ``.ac kind points start stop`` (its ``acan.c``): for ``"dec"``,
    ``floor(points × decades)`` equal ratios from ``start`` to ``stop``, both included; for ``"oct"``, the ratio
    ``2^(1/points)`` from ``start`` while not past ``stop``; for ``"lin"``, ``points`` equally spaced.

    >>> sweep("dec", 7, 3, 20e3)[:3].round(4).tolist()    # 26 steps of (20000/3)^(1/26)
    [3.0, 4.2092, 5.9057]
    >>> sweep("lin", 3, 10, 30).tolist()
    [10.0, 20.0, 30.0]
    """
    try:
        start, stop = float(start), float(stop)
        whole = int(points) if float(points) == int(points) else None
    except (TypeError, ValueError, OverflowError):
        raise ModelError(f"a sweep takes a count and two frequencies, got {points!r}, {start!r}, {stop!r}.") from None
    if kind not in ("dec", "oct", "lin"):
        raise ModelError(f"a sweep is 'dec', 'oct' or 'lin', not {kind!r}.")
    if not (0 < start <= stop < math.inf) or whole is None or whole < 1 or (kind != "lin" and start == stop):
        raise ModelError(f"a {kind} sweep needs 0 < start < stop (finite) and a whole number of points ≥ 1, "
                         f"got {start!r}, {stop!r}, {points!r}.")
    if kind == "lin":
        return np.linspace(start, stop, whole) if whole > 1 else np.array([start])
    span = math.log(stop / start)
    steps = int(math.floor(whole * span / math.log(10.0 if kind == "dec" else 2.0) + 1e-9))
    if kind == "oct":  # a ratio of 2^(1/points) from start, up to stop
        return start * 2.0 ** (np.arange(steps + 1) / whole)
    if steps < 1:
        return np.array([start])
    return start * np.exp(span * np.arange(steps + 1) / steps)


#: From this many unknowns on, a Laplace-form matrix that is banded once reordered (reverse Cuthill–McKee), with a
#: band narrower than a quarter of it, is solved frequency by frequency by LAPACK's banded solver instead of dense
#: batched solves: measured on a 100-section RLC ladder (100 loop charges, tridiagonal), 1,000 frequencies take
#: 0.02 s instead of 0.9 s.
BANDED_MIN = 40

#: Up to this many unknowns the system is solved for every frequency at once, frequencies the last axis, by
#: Gaussian elimination without pivoting that each frequency checks by its backward error (as the banded solve):
#: LAPACK's batched solves pay a call per frequency.  Measured at 1,001 frequencies (random complex systems): 1
#: unknown 0.03 ms against 0.18 ms, 4 unknowns 0.22 ms against 0.51 ms, 8 unknowns 0.96 ms against 1.43 ms, 12
#: unknowns 2.7 ms against 1.7 ms.
SMALL_MAX = 8


def _solve(lin: LinearModel, svals: np.ndarray) -> np.ndarray:
    """``H(s)`` (len(s) × outputs × inputs) by solves of the Laplace-form system: banded when that pays, all
    frequencies at once when small, else dense and batched."""
    _numeric(lin, "a numeric response")
    n, N, ni = len(lin.coordinates), lin.size, len(lin.inputs)
    band = _band(lin) if N >= BANDED_MIN else None
    if band is not None:
        return _solve_banded(lin, svals, *band)
    if N <= SMALL_MAX:
        return _solve_small(lin, svals)
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    chunk = max(1, int(2e7 // max(N * N, 1)))
    m = lin.Phi.shape[0]
    inverse = np.any(lin.Bi) or np.any(lin.Di)
    for lo in range(0, len(svals), chunk):
        sv = svals[lo:lo + chunk][:, None, None]
        P = np.zeros((len(sv), N, N), dtype=complex)
        block = P[:, :n, :n]  # (M s + C) s + K, in place
        np.multiply(lin.M, sv, out=block)
        block += lin.C
        block *= sv
        block += lin.K
        if m:
            P[:, :n, n:] = -lin.Phi.T
            P[:, n:, :n] = lin.Phi
        rhs = np.zeros((len(sv), N, ni), dtype=complex)
        _horner(lin.B, sv, rhs[:, :n, :])
        with np.errstate(divide="ignore", invalid="ignore"):
            if inverse:
                rhs[:, :n, :] += lin.Bi / sv
            try:
                X = np.linalg.solve(P, rhs)
            except np.linalg.LinAlgError:
                X = _singular_solve(P, rhs)
            # every output row at every frequency by one matrix product per power of s: (frequencies × inputs, n)
            # times (n, outputs), then Σ s^k by Horner's rule, in place
            Xq = X[:, :n, :].transpose(0, 2, 1).reshape(-1, n)
            H = np.zeros((len(sv), ni, len(lin.outputs)), dtype=complex)
            for c in reversed(lin.Cq):
                H *= sv
                H += (Xq @ c.T).reshape(len(sv), ni, -1)
            H = H.transpose(0, 2, 1)
            _horner(lin.D, sv, H, add=True)
            if inverse:
                H += lin.Di / sv
        out[lo:lo + chunk] = H
    return out


def _solve_small(lin: LinearModel, svals: np.ndarray) -> np.ndarray:
    """:func:`_solve` for a system of at most :data:`SMALL_MAX` unknowns: ``(M s + C) s + K`` (with the constraint
    blocks) for every frequency at once, frequencies last and contiguous, solved by :func:`_eliminate_small`; a
    frequency whose backward error exceeds :data:`BACKWARD` (a small pivot) is solved again by LAPACK, with
    partial pivoting."""
    n, N, ni = len(lin.coordinates), lin.size, len(lin.inputs)
    m = lin.Phi.shape[0]
    inverse = np.any(lin.Bi) or np.any(lin.Di)
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    chunk = max(1, int(4e6 // (N * (N + ni))))
    plan = _elimination_plan((_full(lin, "M") != 0) | (_full(lin, "C") != 0) | (_full(lin, "K") != 0))
    for lo in range(0, len(svals), chunk):
        sv = svals[lo:lo + chunk]
        P = np.zeros((N, N, len(sv)), dtype=complex)
        block = P[:n, :n]
        np.multiply(lin.M[:, :, None], sv, out=block)
        block += lin.C[:, :, None]
        block *= sv
        block += lin.K[:, :, None]
        if m:
            P[:n, n:] = -lin.Phi.T[:, :, None]
            P[n:, :n] = lin.Phi[:, :, None]
        rhs = np.zeros((N, ni, len(sv)), dtype=complex)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            _horner([b[:, :, None] for b in lin.B], sv, rhs[:n])
            if inverse:
                rhs[:n] += lin.Bi[:, :, None] / sv
            Y = _eliminate_small(P.copy(), rhs.copy(), plan)
            bad = np.flatnonzero(~(_small_backward_error(P, Y, rhs) <= BACKWARD))
            if len(bad):
                P_bad, rhs_bad = np.moveaxis(P[:, :, bad], -1, 0), np.moveaxis(rhs[:, :, bad], -1, 0)
                try:
                    fixed = np.linalg.solve(P_bad, rhs_bad)
                except np.linalg.LinAlgError:
                    fixed = _singular_solve(P_bad, rhs_bad)
                Y[:, :, bad] = np.moveaxis(fixed, 0, -1)
            H = np.zeros((len(lin.outputs), ni, len(sv)), dtype=complex)
            Yq = Y[:n].reshape(n, -1)  # (coordinate, input × frequency): each Cq_k by one matrix product
            for c in reversed(lin.Cq):  # Σ s^k Cq_k y, by Horner's rule
                H *= sv
                H += (c @ Yq).reshape(H.shape)
            _horner([d[:, :, None] for d in lin.D], sv, H, add=True)
            if inverse:
                H += lin.Di[:, :, None] / sv
        out[lo:lo + chunk] = np.moveaxis(H, -1, 0)
    return out


#: The most entry updates (fill-in included) for which :func:`_eliminate_small` eliminates entry by entry along the
#: pattern of nonzeros rather than by blocks: measured at 1,001 frequencies, a Butterworth ladder's 4 unknowns (3
#: updates) 0.056 ms against 0.111 ms, a full 6 × 6 (55 updates) 0.285 ms against 0.264 ms.
ENTRYWISE_MAX = 50


def _elimination_plan(pattern: np.ndarray) -> tuple[list, list] | None:
    """For a small system's pattern of nonzeros: per pivot ``k``, the rows below it to eliminate and the columns
    right of it in its row (fill-in added as it appears), and per row from the last, the columns right of its
    pivot; ``None`` when more than :data:`ENTRYWISE_MAX` entries would be updated (blocks are then faster)."""
    filled = pattern.copy()
    N = len(filled)
    steps, updates = [], 0
    for k in range(N - 1):
        rows = [i for i in range(k + 1, N) if filled[i, k]]
        cols = [j for j in range(k + 1, N) if filled[k, j]]
        updates += len(rows) * len(cols)
        for i in rows:
            filled[i, cols] = True
        steps.append((k, rows, cols))
    if updates > ENTRYWISE_MAX:
        return None
    return steps, [(k, [j for j in range(k + 1, N) if filled[k, j]]) for k in range(N - 1, -1, -1)]


def _eliminate_small(A: np.ndarray, y: np.ndarray, plan: tuple[list, list] | None = None) -> np.ndarray:
    """Solve ``A y = b`` (``A[i, j, f]``, ``y[i, r, f]`` holding ``b``) in place by Gaussian elimination without
    pivoting, every frequency ``f`` at once: entry by entry along ``plan`` (:func:`_elimination_plan`) when given,
    else by blocks.  A zero pivot leaves ``inf`` or ``nan``, which the caller's check catches."""
    if plan is not None:
        steps, back = plan
        for k, rows, cols in steps:
            for i in rows:
                factor = A[i, k] / A[k, k]
                for j in cols:
                    A[i, j] -= factor * A[k, j]
                y[i] -= factor * y[k]
        for k, cols in back:
            for j in cols:
                y[k] -= A[k, j] * y[j]
            y[k] /= A[k, k]
        return y
    N = A.shape[0]
    for k in range(N - 1):
        factor = A[k + 1:, k] / A[k, k]
        A[k + 1:, k + 1:] -= factor[:, None] * A[k, k + 1:][None]
        y[k + 1:] -= factor[:, None] * y[k][None]
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            y[k] -= np.einsum("jf,jrf->rf", A[k, k + 1:], y[k + 1:])
        y[k] /= A[k, k]
    return y


def _small_backward_error(A: np.ndarray, y: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per frequency, ``max_i |A y − b|_i / (|A| |y| + |b|)_i`` (``nan`` where the solve broke down)."""
    r = np.abs(np.einsum("ijf,jrf->irf", A, y) - b)
    scale = np.einsum("ijf,jrf->irf", np.abs(A), np.abs(y)) + np.abs(b)
    ratio = r / scale
    ratio[(scale == 0) & (r == 0)] = 0.0
    return ratio.reshape(-1, A.shape[-1]).max(axis=0)


def _horner(coefficients: Sequence[np.ndarray], sv: np.ndarray, out: np.ndarray, add: bool = False) -> None:
    """``Σ_k c_k s^k`` at every ``s`` of ``sv`` (frequencies first) written into ``out``, or added to it: Horner's
    rule, in place."""
    if not any(np.any(c) for c in coefficients):
        if not add:
            out[...] = 0
        return
    acc = np.zeros_like(out)
    for c in reversed(coefficients):
        acc *= sv
        acc += c
    if add:
        out += acc
    else:
        out[...] = acc


def _full(lin: LinearModel, which: str) -> np.ndarray:
    """One of the Laplace-form system's coefficient matrices over all unknowns (coordinates, then multipliers):
    ``"M"``, ``"C"``, ``"K"`` (the constraint blocks with ``K``)."""
    n, N = len(lin.coordinates), lin.size
    out = np.zeros((N, N))
    out[:n, :n] = getattr(lin, which)
    if which == "K" and N > n:
        out[:n, n:] = -lin.Phi.T
        out[n:, :n] = lin.Phi
    return out


def _band(lin: LinearModel) -> tuple[np.ndarray, int, int] | None:
    """``(permutation, lower, upper)`` bandwidths of the system reordered by reverse Cuthill–McKee, or ``None`` when
    the band is wider than a quarter of the system."""
    import scipy.sparse.csgraph

    N = lin.size
    pattern = (_full(lin, "M") != 0) | (_full(lin, "C") != 0) | (_full(lin, "K") != 0)
    pattern |= pattern.T
    perm = scipy.sparse.csgraph.reverse_cuthill_mckee(scipy.sparse.csr_matrix(pattern), symmetric_mode=True)
    rows, cols = np.nonzero(pattern[np.ix_(perm, perm)])
    lower, upper = int(np.max(rows - cols, initial=0)), int(np.max(cols - rows, initial=0))
    return (perm, lower, upper) if lower + upper + 1 <= N // 4 else None


def _solve_banded(lin: LinearModel, svals: np.ndarray, perm: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """``H(s)`` by a banded LU without pivoting, run for a chunk of frequencies at once (:func:`_band_solve`), each
    answer checked by its residual: a frequency whose backward error exceeds :data:`BACKWARD` (a tiny pivot near a
    resonance of part of the network) is solved again by LAPACK's banded solver with partial pivoting (``gbsv``).
    Frequencies are the last, contiguous axis of every array.  A 100-section ladder at 1,000 frequencies: 6.2 ms,
    where ``gbsv`` frequency by frequency took 18 ms."""
    n, N, ni = len(lin.coordinates), lin.size, len(lin.inputs)
    width = lower + upper + 1
    rows = np.repeat(np.arange(N), width)
    cols = rows + np.tile(np.arange(width), N) - lower
    inside = (cols >= 0) & (cols < N)
    bands = []  # each matrix reordered, by rows: band[i, d] = A[i, i + d − lower]
    for which in "MCK":
        band = np.zeros(N * width)
        band[inside] = _full(lin, which)[np.ix_(perm, perm)][rows[inside], cols[inside]]
        bands.append(band.reshape(N, width, 1))
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    # frequencies at a time: a few MB of arrays, which the allocator keeps (measured on the 100-section ladder: 6.2 ms
    # in chunks of 625 frequencies, 7.5–9 ms in one of 1,000, whose freed arrays go back to the system and fault in
    # again), and at least 256, so that the loops over rows pay off
    chunk = max(256, int(2.5e5 // (N * (width + ni))))
    B = [b[perm] for b in _padded_rows(lin.B, N, n)]  # the right-hand sides' rows reordered with the unknowns
    Bi = _padded_rows([lin.Bi], N, n)[0][perm]
    for lo in range(0, len(svals), chunk):
        sv = svals[lo:lo + chunk]
        A = bands[0] * sv  # (M s + C) s + K, in place: one array of the chunk's size, not four
        A += bands[1]
        A *= sv
        A += bands[2]
        with np.errstate(divide="ignore", invalid="ignore"):
            rhs = sum(b[:, :, None] * sv**k for k, b in enumerate(B)) + (Bi[:, :, None] / sv if np.any(Bi) else 0)
            D = sum(d[None] * sv[:, None, None]**k for k, d in enumerate(lin.D)) + (
                lin.Di[None] / sv[:, None, None] if np.any(lin.Di) else 0)
            Y = _band_solve(A, rhs, lower, upper)
            bad = ~(_backward_error(A, Y, rhs, lower) <= BACKWARD)
        for f in np.flatnonzero(bad):
            Y[:, :, f] = _gbsv(A[:, :, f], rhs[:, :, f], lower, upper)
        X = np.empty_like(Y)
        X[perm] = Y
        Xq = X[:n].reshape(n, -1)  # (coordinate, input × frequency): the outputs by one matrix product a power
        H = sum((c @ Xq).reshape(len(c), ni, -1) * sv**k for k, c in enumerate(lin.Cq))
        out[lo:lo + chunk] = np.moveaxis(H, -1, 0) + D
    return out


def _padded_rows(mats: list, N: int, n: int) -> list[np.ndarray]:
    """Input matrices over the ``n`` coordinates, padded with zero rows to all ``N`` unknowns (the multipliers')."""
    out = []
    for m in mats:
        full = np.zeros((N, np.shape(m)[1]), dtype=complex)
        full[:n] = m
        out.append(full)
    return out


#: The largest componentwise backward error (``max |A y − b| / (|A| |y| + |b|)``) a banded solve without pivoting
#: may leave before the frequency is solved again with pivoting: a few hundred units of round-off.
BACKWARD = 256 * np.finfo(float).eps


def _band_solve(A: np.ndarray, b: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """Solve ``A y = b`` for banded matrices over a last axis of frequencies (``A[i, d, f] = A_f[i, i + d − lower]``,
    ``b[i, r, f]``) by Gaussian elimination without pivoting, every frequency at once: the loops run over the
    rows, NumPy over contiguous frequencies.  A zero pivot leaves ``inf`` or ``nan``, which the caller's residual
    check catches."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if lower == upper == 1:
            return _tridiagonal(A, b.copy())
        return _eliminate(A.copy(), b.copy(), lower, upper)


def _tridiagonal(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    """:func:`_eliminate` of a tridiagonal system (a ladder, a chain), ``A`` left as it is: only the pivots are
    new (``d``), the sub-diagonal is read once for its factor and the super-diagonal is the eliminated rows' own."""
    N, F = A.shape[0], A.shape[-1]
    d = np.empty((N, F), dtype=complex)
    d[0] = A[0, 1]
    factor = np.empty(F, dtype=complex)
    for i in range(1, N):
        np.divide(A[i, 0], d[i - 1], out=factor)
        np.multiply(factor, A[i - 1, 2], out=d[i])
        np.subtract(A[i, 1], d[i], out=d[i])
        y[i] -= factor * y[i - 1]
    y[N - 1] /= d[N - 1]
    for i in range(N - 2, -1, -1):
        y[i] -= A[i, 2] * y[i + 1]
        y[i] /= d[i]
    return y


def _eliminate(A: np.ndarray, y: np.ndarray, lower: int, upper: int) -> np.ndarray:
    N = A.shape[0]
    for k in range(N - 1):
        pivot = A[k, lower]
        for i in range(k + 1, min(N, k + lower + 1)):
            d = k - i + lower  # row i, column k
            factor = A[i, d] / pivot
            A[i, d:d + upper + 1] -= factor * A[k, lower:]
            y[i] -= factor * y[k]
    for k in range(N - 1, -1, -1):
        for j in range(1, min(upper, N - 1 - k) + 1):
            y[k] -= A[k, lower + j] * y[k + j]
        y[k] /= A[k, lower]
    return y


def _backward_error(A: np.ndarray, y: np.ndarray, b: np.ndarray, lower: int) -> np.ndarray:
    """Per frequency, ``max_i |A y − b|_i / (|A| |y| + |b|)_i`` (``nan`` where the solve broke down)."""
    N, width = A.shape[0], A.shape[1]
    r, scale = -b, np.abs(b)  # fresh arrays: b is not written
    for d in range(width):
        j0, j1 = max(0, lower - d), min(N, N + lower - d)  # rows whose column i + d − lower exists
        if j1 <= j0:
            continue
        term = A[j0:j1, d, None] * y[j0 + d - lower:j1 + d - lower]
        r[j0:j1] += term
        scale[j0:j1] += np.abs(term)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(r) / scale
    ratio[(scale == 0) & (r == 0)] = 0.0
    return ratio.reshape(-1, A.shape[-1]).max(axis=0)


def _gbsv(A: np.ndarray, b: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """One frequency's banded system (``A[i, d]``, ``b[i, r]``) by LAPACK's ``gbsv`` (partial pivoting); ``inf``
    when it is singular (a pole on the grid)."""
    import scipy.linalg

    N, width = A.shape
    ab = np.zeros((2 * lower + upper + 1, N), dtype=complex)  # gbsv's storage: ab[lower + upper + i − j, j] = A[i, j]
    for d in range(width):  # the first ``lower`` rows: room for the pivoting's fill-in
        j0, j1 = max(0, lower - d), min(N, N + lower - d)
        if j1 <= j0:
            continue
        ab[2 * lower + upper - d, j0 + d - lower:j1 + d - lower] = A[j0:j1, d]
    gbsv, = scipy.linalg.get_lapack_funcs(("gbsv",), (ab,))
    _, _, y, info = gbsv(lower, upper, ab, np.array(b, dtype=complex))
    return y if info == 0 else np.full(b.shape, np.inf, dtype=complex)


def _singular_solve(P: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve frequency by frequency, with ``inf`` where the system is singular (a pole on the grid)."""
    X = np.empty_like(rhs)
    for i in range(len(P)):
        try:
            X[i] = np.linalg.solve(P[i], rhs[i])
        except np.linalg.LinAlgError:
            X[i] = np.inf
    return X


# ---------------------------------------------------------------------------
# Transfer functions
# ---------------------------------------------------------------------------


@dataclass
class TransferFunction:
    """``H(s)`` from one input to one output of a linearized model (``inverse``: ``1/H``, for impedances).

    Call it with ``s`` values (complex) for numbers; :attr:`expr` is the
    rational function, :meth:`poles`, :meth:`zeros` and :attr:`dc_gain`
    describe it.
    """

    linear: LinearModel
    input: str
    output: str
    inverse: bool = False
    _expr: Any = field(default=None, repr=False)

    def __repr__(self) -> str:
        what = f"1 / ({self.output} / {self.input})" if self.inverse else f"{self.output} / {self.input}"
        return f"<TransferFunction {what} of {self.linear.model!r}>"

    def _pick(self) -> LinearModel:
        lin = self.linear
        i, o = lin.inputs.index(self.input), lin.outputs.index(self.output)
        return LinearModel(**{**lin.__dict__, "inputs": [self.input], "outputs": [self.output],
                              "B": [b[:, i:i + 1] for b in lin.B], "Bi": lin.Bi[:, i:i + 1], "Di": lin.Di[o:o + 1, i:i + 1],
                              "Cq": [c[o:o + 1, :] for c in lin.Cq],
                              "D": [d[o:o + 1, i:i + 1] for d in lin.D]})

    def __call__(self, svals) -> np.ndarray | complex:
        scalar = np.ndim(svals) == 0
        sv = np.atleast_1d(np.asarray(svals, dtype=complex))
        H = _solve(self._pick(), sv)[:, 0, 0]
        if self.inverse:
            with np.errstate(divide="ignore", invalid="ignore"):
                H = 1 / H
        return complex(H[0]) if scalar else H

    @property
    def expr(self) -> sp.Expr:
        """``H(s)`` as a SymPy rational function of :data:`s`, in lowest terms.

        Solved in exact arithmetic (the parameters' symbols, or the binary
        values of their floating-point numbers as rationals, so factors that
        cancel cancel exactly) for at most :data:`SYMBOLIC_MAX` unknowns;
        with numbers its coefficients are then floats, the denominator
        monic.  A larger numeric model's comes from its poles, zeros and
        gain, with coinciding pole–zero pairs cancelled."""
        if self._expr is None:
            if self.linear.size <= SYMBOLIC_MAX or self.linear.symbolic:
                self._expr = self._exact()
            else:
                self._expr = self._from_roots()
        return self._expr

    def _exact(self) -> sp.Expr:
        lin = self._pick()
        if lin.size > SYMBOLIC_MAX:
            raise ModelError(f"model {lin.model!r}: a symbolic transfer function of {lin.size} unknowns is beyond "
                             f"{SYMBOLIC_MAX}; give the parameters values (params=) for a numeric one.")
        if not lin.symbolic:  # the floats' exact binary values: what cancels, cancels exactly
            lin = _rational(lin)
        P, rhs = lin.pencil(s)
        X = sp.Matrix(P).LUsolve(sp.Matrix(rhs))
        Cq, D = lin.output_rows(s)
        n = len(lin.coordinates)
        H = sp.cancel(sp.together((sp.Matrix(Cq) * X[:n, :] + sp.Matrix(D))[0, 0]))
        if self.inverse:
            H = sp.cancel(1 / H)
        if self.linear.symbolic:
            return sp.factor(H)
        num, den = sp.fraction(H)
        num, den = sp.Poly(num, s), sp.Poly(den, s)
        lead = den.LC()
        return (sp.Poly([sp.Float(c / lead) for c in num.all_coeffs()], s).as_expr()
                / sp.Poly([sp.Float(c / lead) for c in den.all_coeffs()], s).as_expr())

    def _from_roots(self) -> sp.Expr:
        z, p = self._roots()
        w0 = _scale(self.linear)
        probe = complex(0.173 * w0, 0.911 * w0)
        value = complex(self(probe))
        gain = value * np.prod([probe - x for x in p]) / np.prod([probe - x for x in z])
        if abs(gain.imag) <= 1e-8 * abs(gain):
            gain = gain.real
        num = np.real_if_close(np.poly(z) * gain, tol=1e6) if len(z) else np.array([gain])
        den = np.real_if_close(np.poly(p), tol=1e6) if len(p) else np.array([1.0])
        poly = (lambda c: sum(sp.Float(x) * s ** (len(c) - 1 - i) if np.isreal(x) else sp.sympify(complex(x)) * s ** (len(c) - 1 - i)
                              for i, x in enumerate(c)))
        return poly(np.atleast_1d(num)) / poly(np.atleast_1d(den))

    def poles(self) -> np.ndarray:
        """The finite poles of ``H`` (rad/s, complex), sorted by magnitude.

        A mode that the input does not reach or the output does not see
        cancels against a zero and is not a pole of ``H`` (the drift of a
        loop charge, seen only through its rate).  Up to
        :data:`SYMBOLIC_MAX` unknowns they are the roots of the exact
        rational function's denominator; beyond, the generalized eigenvalues
        of the linearization's pencil, less those matched by an invariant
        zero.
        """
        return self._roots()[1]

    def zeros(self) -> np.ndarray:
        """The finite zeros of ``H`` (rad/s, complex), sorted by magnitude, as :meth:`poles`: the roots of the
        numerator, or the invariant zeros (where ``[[A − sE, B], [C, D]]`` loses rank) less those matched by a
        pole."""
        return self._roots()[0]

    def _roots(self) -> tuple[np.ndarray, np.ndarray]:
        lin = self._pick()
        _numeric(lin, "poles and zeros")
        if lin.size <= SYMBOLIC_MAX:
            num, den = sp.fraction(self.expr)
            return _sorted(_poly_roots(num)), _sorted(_poly_roots(den))
        w0 = _scale(lin)
        z = _eigenvalues(_descriptor(lin, with_io=True), w0)
        p = _eigenvalues(_descriptor(lin, with_io=False), w0)
        z, p = _cancel(z, p, w0)
        return (p, z) if self.inverse else (z, p)

    @property
    def dc_gain(self) -> float | complex:
        """``H(0)``; ``inf`` where a pole sits at ``s = 0`` (a free mass, a capacitor with no path to ground)."""
        if self.linear.symbolic:
            return sp.limit(self.expr, s, 0)
        if self.linear.size <= SYMBOLIC_MAX:
            num, den = sp.fraction(self.expr)
            n0, d0 = complex(num.subs(s, 0)), complex(den.subs(s, 0))
            if d0 == 0:  # an exact zero of the denominator (the coefficients are exact up to this point)
                return math.inf if n0 != 0 else float(sp.limit(self.expr, s, 0))
            value = n0 / d0
            return value.real if abs(value.imag) <= 1e-12 * abs(value) else value
        with np.errstate(all="ignore"):
            if not (np.any(self._pick().Bi) or np.any(self._pick().Di)):
                value = complex(self(0.0))
            else:  # u/s terms: the limit s → 0, extrapolated from three points along the real axis
                eps = 1e-4 * _scale(self.linear)
                h1, h2, h4 = (complex(self(eps / k)) for k in (1, 2, 4))
                growing = abs(h4) > 3 * abs(h2) > 9 * abs(h1)  # like 1/s: a pole at s = 0
                value = complex("inf") if growing else (8 * h4 - 6 * h2 + h1) / 3
        if not np.isfinite(value):
            return math.inf
        return value.real if abs(value.imag) <= 1e-12 * abs(value) else value


def transfer_function(system: Model | LinearModel, input: str, output: Any, **kwargs: Any) -> TransferFunction:
    """``H(s)`` from ``input`` (a source or load component) to ``output`` (a coordinate, ``"v(C1)"``, ...).

    ``kwargs`` go to :func:`linearize` (``at``, ``params``, ``time``, ``symbolic``).
    """
    lin = _linear(system, [input], [output], kwargs)
    return TransferFunction(lin, lin.inputs[0] if isinstance(system, Model) else input,
                            lin.outputs[0] if isinstance(system, Model) else str(output))


def impedance(system: Model, source: str, **kwargs: Any) -> TransferFunction:
    """The driving-point impedance ``Z(s)`` the circuit presents to ``source``.

    For a voltage source it is ``E / i`` with ``i`` the current the source
    delivers (out of its ``a`` terminal into the circuit); for a current
    source, the voltage across the circuit between the nodes it drives
    over its current.  Mechanical impedance is the same with a force as
    the source and the driven point's velocity as the output.
    """
    comp = system.component(source)
    if comp.kind == "voltage_source":
        lin = linearize(system, inputs=[source], outputs=[f"i({source})"], **kwargs)
        lin = _negated(lin)
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0], inverse=True)
    if comp.kind == "current_source":
        lin = _negated(linearize(system, inputs=[source], outputs=[f"v({source})"], **kwargs))
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0])
    if comp.kind == "force":
        node = comp.nodes[0]
        velocity = [nm for nm in system.coordinate_names if nm == f"x_{node}"]
        if not velocity:
            raise ModelError(f"force {source!r}: its node {node!r} has no coordinate of its own; give the output "
                             f"with transfer_function(model, {source!r}, <velocity>).")
        lin = linearize(system, inputs=[source], outputs=[f"x_{node}'"], **kwargs)
        return TransferFunction(lin, lin.inputs[0], lin.outputs[0], inverse=True)
    raise ModelError(f"impedance takes a voltage source, a current source or a force; {source!r} is a {comp.kind}.")


def _cancel(zeros: np.ndarray, poles: np.ndarray, w0: float, tol: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
    """Zeros and poles with the pairs that coincide (within ``tol`` of ``w0`` or of their size) removed: modes the
    input does not reach or the output does not see."""
    zeros, poles = list(zeros), list(poles)
    for z in list(zeros):
        near = [i for i, p in enumerate(poles) if abs(p - z) <= tol * max(w0, abs(z))]
        if near:
            poles.pop(near[0])
            zeros.remove(z)
    return np.array(zeros, dtype=complex), np.array(poles, dtype=complex)


def _poly_roots(expr: sp.Expr) -> np.ndarray:
    """The roots of a polynomial in :data:`s` with number coefficients; a factor ``s^k`` gives ``k`` exact zeros."""
    coeffs = [complex(c) for c in sp.Poly(expr, s).all_coeffs()]
    k = 0
    while len(coeffs) > 1 and coeffs[-1] == 0:  # exact zeros: the coefficients come from exact arithmetic
        coeffs.pop()
        k += 1
    roots = np.roots(coeffs) if len(coeffs) > 1 else np.zeros(0, dtype=complex)
    return np.concatenate([roots.astype(complex), np.zeros(k, dtype=complex)])


def _sorted(roots: np.ndarray) -> np.ndarray:
    roots = np.where(np.abs(roots.imag) <= 1e-12 * np.abs(roots), roots.real + 0j, roots)
    return roots[np.lexsort((roots.imag, np.abs(roots)))]


def _rational(lin: LinearModel) -> LinearModel:
    """``lin`` with every matrix in exact rationals (each float's own binary value)."""
    def exact(a):
        return sp.Matrix(a.shape[0], a.shape[1], [sp.Rational(float(x)) for x in np.ravel(a)])

    return LinearModel(**{**lin.__dict__, "symbolic": True, "M": exact(lin.M), "C": exact(lin.C), "K": exact(lin.K),
                          "Phi": exact(lin.Phi), "B": [exact(b) for b in lin.B], "Bi": exact(lin.Bi),
                          "Cq": [exact(c) for c in lin.Cq], "D": [exact(d) for d in lin.D], "Di": exact(lin.Di)})


def _negated(lin: LinearModel) -> LinearModel:
    return LinearModel(**{**lin.__dict__, "Cq": [-c for c in lin.Cq], "D": [-d for d in lin.D], "Di": -lin.Di})


# ---------------------------------------------------------------------------
# Frequency response
# ---------------------------------------------------------------------------


@dataclass
class FrequencyResponse:
    """``H(j 2π f)`` of every output to every input (``H[output, input]`` over :attr:`frequencies`, Hz)."""

    model: str
    frequencies: np.ndarray
    inputs: list[str]
    outputs: list[str]
    H: np.ndarray  # outputs × inputs × frequencies
    notes: list[str] = field(default_factory=list)
    #: units of the inputs and outputs by label (``""`` where unknown)
    units: dict[str, str] = field(default_factory=dict)

    def unit(self, output: Any, input: str) -> str:
        """The unit of ``H[output, input]`` (``"V/A"``, ``"m/N"``, ``"V/V"``), or ``""`` when either is unknown."""
        top, bottom = self.units.get(str(output), ""), self.units.get(input, "")
        if not top or not bottom:
            return ""
        num, _, den = top.partition("/")
        den = " ".join(x for x in (den, bottom) if x)
        return f"{num}/{den}" if " " not in den else f"{num}/({den})"

    def __repr__(self) -> str:
        return (f"<FrequencyResponse of {self.model!r}: {len(self.outputs)} output(s) × {len(self.inputs)} input(s), "
                f"{len(self.frequencies)} frequencies {self.frequencies[0]:g}–{self.frequencies[-1]:g} Hz>")

    def __getitem__(self, key) -> np.ndarray:
        """``resp["v(C1)"]`` (the only input) or ``resp["v(C1)", "V1"]``: the complex response."""
        out, inp = key if isinstance(key, tuple) else (key, None)
        o = self._index(self.outputs, out, "output")
        if inp is None:
            if len(self.inputs) != 1:
                raise ModelError(f"this response has inputs {self.inputs}: name one, as resp[{out!r}, {self.inputs[0]!r}].")
            i = 0
        else:
            i = self._index(self.inputs, inp, "input")
        return self.H[o, i]

    @staticmethod
    def _index(names: list[str], name: Any, what: str) -> int:
        key = str(name)
        if key not in names:
            raise UnknownNameError(what, key, names)
        return names.index(key)

    def magnitude_db(self, output: Any, input: str | None = None) -> np.ndarray:
        """``20 log10 |H|``."""
        with np.errstate(divide="ignore"):
            return 20 * np.log10(np.abs(self[output, input] if input else self[output]))

    def phase_deg(self, output: Any, input: str | None = None) -> np.ndarray:
        """The phase of ``H`` in degrees, unwrapped along the frequency grid."""
        return np.degrees(np.unwrap(np.angle(self[output, input] if input else self[output])))

    def _legend(self, output: str, input: str) -> str:
        unit = self.unit(output, input)
        return f"{output} / {input}" + (f" ({unit})" if unit else "")

    def plot(self, kind: str = "bode", *, outputs: Sequence[Any] | None = None, input: str | None = None,
             path: str | None = None):
        """A Bode chart (magnitude in dB and phase against log frequency) or a Nyquist chart; returns the matplotlib
        Figure and writes it to ``path`` (PNG) when given."""
        import matplotlib.pyplot as plt

        if kind not in ("bode", "nyquist"):
            raise ModelError(f"kind is 'bode' or 'nyquist', not {kind!r}.")
        chosen = [str(o) for o in (outputs or self.outputs)]
        inp = input or self.inputs[0]
        if kind == "bode":
            fig, (ax_m, ax_p) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
            for o in chosen:
                ax_m.semilogx(self.frequencies, self.magnitude_db(o, inp), label=self._legend(o, inp))
                ax_p.semilogx(self.frequencies, self.phase_deg(o, inp), label=self._legend(o, inp))
            ax_m.set_ylabel("|H| (dB re 1 unit of each ratio)" if any(self.unit(o, inp) for o in chosen)
                            else "|H| (dB)")
            ax_p.set_ylabel("phase (°)")
            ax_p.set_xlabel("frequency (Hz)")
            ax_m.legend(fontsize=8)
            for ax in (ax_m, ax_p):
                ax.grid(True, which="both", alpha=0.3)
        else:
            fig, ax = plt.subplots(figsize=(6, 6))
            for o in chosen:
                H = self[o, inp]
                ax.plot(H.real, H.imag, label=self._legend(o, inp))
                ax.plot(H.real, -H.imag, "--", alpha=0.4)
            ax.plot([-1], [0], "r+")
            units = {self.unit(o, inp) for o in chosen}
            suffix = f" ({units.pop()})" if len(units) == 1 and "" not in units else ""
            ax.set_xlabel(f"Re H{suffix}")
            ax.set_ylabel(f"Im H{suffix}")
            ax.axis("equal")
            ax.legend(fontsize=8)
            ax.grid(True, alpha=0.3)
        fig.suptitle(f"{self.model}: frequency response")
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
        return fig


def frequency_response(system: Model | LinearModel, frequencies: Any, *, inputs: Sequence[str] | None = None,
                       outputs: Sequence[Any] | None = None, **kwargs: Any) -> FrequencyResponse:
    """``H(j 2π f)`` at ``frequencies`` (Hz) for every input and output (see :func:`linearize` for both and for
    ``kwargs``)."""
    f = np.atleast_1d(np.asarray(frequencies, dtype=float)) if not isinstance(frequencies, str) else None
    if f is None or f.ndim != 1 or not len(f) or not np.all(np.isfinite(f)) or np.any(f < 0):
        raise ModelError(f"frequencies are a 1-D sequence of finite, non-negative numbers (Hz), got {frequencies!r:.80}.")
    lin = _linear(system, inputs, outputs, kwargs)
    H = _solve(lin, 2j * np.pi * f)
    notes = []
    if not np.all(np.isfinite(H)):
        bad = f[~np.all(np.isfinite(H), axis=(1, 2))]
        notes.append(f"not finite at {len(bad)} frequencies (a pole on the grid, first at {bad[0]:g} Hz)")
    return FrequencyResponse(lin.model, f, list(lin.inputs), list(lin.outputs), np.moveaxis(H, 0, -1), notes,
                             dict(lin.units))
