"""Solving the Laplace form of a linearization at many frequencies at once (what
:func:`lagrangian.frequency.frequency_response` and :class:`~lagrangian.frequency.TransferFunction` evaluate).

``[[M s² + C s + K, −Φ_qᵀ], [Φ_q, 0]] X = [Σ B_k s^k; 0]`` is solved for every ``s`` of a grid, the outputs
being ``(Σ Cq_k s^k) X + Σ D_k s^k``:

- up to :data:`SMALL_MAX` unknowns, every frequency at once (frequencies the last, contiguous axis) by Gaussian
  elimination without pivoting, entry by entry along the pattern of nonzeros when that is sparse;
- from :data:`BANDED_MIN` unknowns, when banded once reordered (a ladder, a chain), the same way over the band
  (a tridiagonal system without copying its matrix);
- in between, or wide, by LAPACK's batched solves.

Each answer obtained without pivoting is checked, frequency by frequency, by its componentwise backward error
(:data:`BACKWARD`); where it exceeds it (a small pivot near a resonance of part of the network) the frequency is
solved again by LAPACK with partial pivoting.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .linearize import LinearModel
from .modes import _numeric


#: From this many unknowns on, a Laplace-form matrix that is banded once reordered (reverse Cuthill–McKee), with a
#: band narrower than a quarter of it, is solved over its band (:func:`_solve_banded`) instead of by dense batched
#: solves: measured on a 100-section RLC ladder (100 loop charges, tridiagonal), 1,000 frequencies take 10 ms
#: instead of 0.9 s.
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
            P[:, :n, n:] = -lin.force_rows().T
            P[:, n:, :n] = lin.Phi
            if lin.velocity_rows:
                P[:, n:, :n] += lin.rate_rows() * sv
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
            P[:n, n:] = -lin.force_rows().T[:, :, None]
            P[n:, :n] = lin.Phi[:, :, None]
            if lin.velocity_rows:
                P[n:, :n] += lin.rate_rows()[:, :, None] * sv
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
    ``"M"``, ``"C"``, ``"K"`` (the constraint blocks with ``K``, the rates' rows of constraints on velocities with
    ``C``)."""
    n, N = len(lin.coordinates), lin.size
    out = np.zeros((N, N))
    out[:n, :n] = getattr(lin, which)
    if which == "K" and N > n:
        out[:n, n:] = -lin.force_rows().T
        out[n:, :n] = lin.Phi
    if which == "C" and lin.velocity_rows:
        out[n:, :n] = lin.rate_rows()
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
    Frequencies are the last, contiguous axis of every array.  A 100-section ladder at 1,000 frequencies: 10 ms
    (9.5–12 ms over runs on a 2-core machine), where ``gbsv`` frequency by frequency took 18 ms."""
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
    # frequencies at a time: a few MB of arrays, which the allocator keeps (measured on the 100-section ladder, each
    # case between runs of ngspice: 18.7–21.4 ms in chunks of 625 frequencies, 22.3–22.7 ms in one of 1,000, whose
    # freed arrays go back to the system and fault in again), and at least 256, so that the loops over rows pay off
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
