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
solved again by LAPACK with partial pivoting, refined to that backward error (:func:`_refined_solve`).  Every value
comes with the bound of its error, and a value without a certain digit is refused (:func:`_respond`).
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
    """``H(s)`` (len(s) × outputs × inputs), ``nan`` where no digit of it is certain (:func:`_respond`)."""
    return _respond(lin, svals)[0]


def _respond(lin: LinearModel, svals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(H, bound, uncertain)``: ``H(s)`` (len(s) × outputs × inputs) by solves of the Laplace-form system (banded
    when that pays, all frequencies at once when small, else dense and batched), the bound of each value's error,
    and where a value was refused.

    Each value comes with the first-order bound of its error, ``16 ε |wᵀ| (|P| |x| + |b|) + 16 ε |c(s)| |x|``, from
    the adjoint solve ``Pᵀ w = c(s)ᵀ`` of its output row ``c(s) = Σ s^k Cq_k`` and ``|P| = |M| |s|² + |C| |s| +
    |K|``: what rounding the entries of ``M``, ``C``, ``K``, ``b`` and the solve (backward-stable, as each path is
    checked to be) can do.  ``P`` formed in doubles may be singular, or nearly, where the exact matrices are not
    (a term ``L s²`` of 4e-8 lost beside a ``1/C`` of 1e8, at a millihertz); its ``w`` is then huge, and so is the
    bound.  A value whose bound is at least its size and above :data:`FLOOR` of the output's peak over the grid
    (the values with a certain digit) has no certain digit: it is refused (``nan``, ``uncertain`` true) rather than returned wrong.

    The small and banded paths first screen the bound from above with their own factors (:func:`_screen`), which
    costs a solve with one real right-hand side; only a value the screen cannot vouch for gets its adjoint solved
    (by LAPACK).  Measured on a 100-section ladder at 1,000 frequencies: 9.7 ms without any bound, 14 ms with the
    screen, 18.5 ms with the adjoint at every frequency.  The dense path solves the adjoint at every frequency
    (with the same solve, as more right-hand sides, when ``P`` is symmetric)."""
    _numeric(lin, "a numeric response")
    N = lin.size
    band = _band(lin) if N >= BANDED_MIN else None
    if band is not None:
        H, bound = _solve_banded(lin, svals, *band)
    elif N <= SMALL_MAX:
        H, bound = _solve_small(lin, svals)
    else:
        H, bound = _solve_dense(lin, svals)
    size = np.abs(H)
    with np.errstate(invalid="ignore"):
        certain = np.isfinite(size) & (bound < size)  # the peak over values with a certain digit, not over garbage
        peak = np.max(np.where(certain, size, 0.0), axis=0, initial=0.0)
        uncertain = np.isfinite(H) & ~(certain | (bound <= FLOOR * peak))
    H[uncertain] = np.nan
    return H, bound, uncertain


#: Below this share of an output's peak over the grid, an error bound is not a reason to refuse a value (a notch's
#: depth, a structural zero: accurate in absolute terms): the floor to which responses are compared with ngspice's.
FLOOR = 1e-12

#: The factor of ``ε`` in the error bound of :func:`_respond`: LAPACK with partial pivoting stays within 1× of its
#: ``ε`` form on random circuits over eight decades, the solves without pivoting within 1.4×.
ROUNDING = 16 * np.finfo(float).eps


def _symmetric(lin: LinearModel) -> bool:
    """Whether ``P(s)`` is symmetric at every ``s`` (no constraints, ``M``, ``C``, ``K`` symmetric), so that the
    adjoint solve is the same solve with more right-hand sides (else a solve of the transpose)."""
    return lin.Phi.shape[0] == 0 and all(np.array_equal(a, a.T) for a in (lin.M, lin.C, lin.K))


def _adjoint_rhs(lin: LinearModel, N: int, sv: np.ndarray, out: np.ndarray | None = None,
                 order: np.ndarray | None = None) -> np.ndarray:
    """The output rows ``c(s)ᵀ = Σ s^k Cq_kᵀ`` padded to all ``N`` unknowns, ``(N, outputs, frequencies)``,
    written into ``out`` when given (zeros), the unknowns reordered by ``order`` when given."""
    if out is None:
        out = np.zeros((N, len(lin.outputs), len(sv)), dtype=complex)
    _add_rows([c.T for c in lin.Cq], sv, out, order)
    return out


def _add_rows(coefficients: Sequence[np.ndarray], sv: np.ndarray, out: np.ndarray,
              order: np.ndarray | None = None) -> None:
    """``out += Σ_k c_k s^k`` (frequencies last) for coefficients over the unknowns (rows) and columns, only over
    the rows some ``c_k`` holds (a source, an output: a row or two of a long chain), the unknowns reordered by
    ``order`` when given (``out[i]`` is row ``order[i]``)."""
    rows = np.flatnonzero(np.any([np.any(c, axis=1) for c in coefficients], axis=0))
    at = rows if order is None else np.argsort(order)[rows]
    for k, c in enumerate(coefficients):
        part = c[rows][:, :, None]
        if np.any(part):
            out[at, :c.shape[1]] += part * sv**k if k else part


def _bound(spread: np.ndarray, W: np.ndarray, X: np.ndarray, lin: LinearModel, sv: np.ndarray,
           omega: np.ndarray) -> np.ndarray:
    """The error bound of :func:`_respond`, ``(outputs, inputs, frequencies)``, from ``spread = |P| |x| + |b|``
    and ``X`` (unknowns × inputs × frequencies) and ``W`` (unknowns × outputs × frequencies), in the same order,
    and each frequency's backward error ``omega`` (:func:`_factor`)."""
    n = len(lin.coordinates)
    c_abs = sum(np.abs(c)[:, :, None] * np.abs(sv) ** k for k, c in enumerate(lin.Cq))
    with np.errstate(invalid="ignore", over="ignore"):
        return _factor(omega) * (np.einsum("iof,irf->orf", np.abs(W), spread)
                                 + np.einsum("ojf,jrf->orf", c_abs, np.abs(X[:n])))


def _factor(omega: np.ndarray) -> np.ndarray:
    """The factor of a bound for solves of measured componentwise backward error ``omega`` (per frequency, against
    ``|M| |s|² + |C| |s| + |K|``): the rounding of forming ``P`` and ``b`` and of the outputs (:data:`ROUNDING`),
    and twice ``omega`` (itself measured in rounded arithmetic)."""
    return ROUNDING + 2 * np.nan_to_num(omega, nan=np.inf)


def _solve_dense(lin: LinearModel, svals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_respond` by LAPACK's batched solves, refined (:func:`_refined_solve`), in chunks of frequencies;
    the adjoint at every frequency."""
    n, N, ni = len(lin.coordinates), lin.size, len(lin.inputs)
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    bounds = np.empty(out.shape)
    chunk = max(1, int(2e7 // max(N * N, 1)))
    m = lin.Phi.shape[0]
    inverse = np.any(lin.Bi) or np.any(lin.Di)
    symmetric = _symmetric(lin)
    absolute = [np.abs(_full(lin, w)) for w in "MCK"]
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
        adjoint = np.moveaxis(_adjoint_rhs(lin, N, sv[:, 0, 0]), -1, 0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            if inverse:
                rhs[:, :n, :] += lin.Bi / sv
            a = np.abs(sv)
            absolute_P = (absolute[0] * a + absolute[1]) * a + absolute[2]
            X, omega, spread = _refined_solve(P, absolute_P, rhs)
            W = _refined_solve(P, absolute_P, adjoint)[0] if symmetric else \
                _refined_solve(P.transpose(0, 2, 1), absolute_P.transpose(0, 2, 1), adjoint)[0]
            bounds[lo:lo + chunk] = np.moveaxis(_bound(*(np.moveaxis(v, 0, -1) for v in (spread, W, X)), lin,
                                                       sv[:, 0, 0], omega), -1, 0)
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
    return out, bounds


def _lapack_solve(P: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Batched solves (frequencies first), frequency by frequency where one of them is singular."""
    try:
        return np.linalg.solve(P, rhs)
    except np.linalg.LinAlgError:
        return _singular_solve(P, rhs)


#: The most steps of iterative refinement a LAPACK solve takes towards a componentwise backward error within
#: :data:`BACKWARD`.
REFINE = 3


def _refined_solve(P: np.ndarray, absolute: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(x, omega, spread)``: batched LAPACK solves (frequencies first) with partial pivoting, refined in working
    precision (``x += P⁻¹ (b − P x)``, at most :data:`REFINE` steps) where the componentwise backward error
    against ``absolute`` (``|M| |s|² + |C| |s| + |K|``) exceeds :data:`BACKWARD`: partial pivoting alone is only
    normwise stable (measured: 4e5 ε on a ladder in node fluxes at a millihertz; one step brings it to ε), and
    one step of refinement makes it componentwise stable (Skeel).  ``omega`` per frequency, ``spread = |P| |x| +
    |b|``."""
    x = _lapack_solve(P, rhs)
    for _ in range(REFINE + 1):
        with np.errstate(invalid="ignore", over="ignore"):
            r = rhs - P @ x
            spread = absolute @ np.abs(x) + np.abs(rhs)
            ratio = np.abs(r) / spread
        ratio[(spread == 0) & (r == 0)] = 0.0
        omega = ratio.reshape(len(P), -1).max(axis=1, initial=0.0)
        again = np.flatnonzero(~(omega <= BACKWARD) & np.isfinite(x).reshape(len(P), -1).all(axis=1))
        if not len(again) or _ == REFINE:
            return x, omega, spread
        x[again] += _lapack_solve(P[again], r[again])
    return x, omega, spread


def _solve_small(lin: LinearModel, svals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_respond` for a system of at most :data:`SMALL_MAX` unknowns: ``(M s + C) s + K`` (with the
    constraint blocks) for every frequency at once, frequencies last and contiguous, solved by
    :func:`_eliminate_small`; a frequency whose backward error exceeds :data:`BACKWARD` (a small pivot) is solved
    again by LAPACK, with partial pivoting, refined (:func:`_refined_solve`).  The error bounds are screened
    (:func:`_screen`)."""
    n, N, ni = len(lin.coordinates), lin.size, len(lin.inputs)
    m = lin.Phi.shape[0]
    inverse = np.any(lin.Bi) or np.any(lin.Di)
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    bounds = np.empty(out.shape)
    chunk = max(1, int(4e6 // (N * (N + ni))))
    absolute = [np.abs(_full(lin, w))[:, :, None] for w in "MCK"]
    pattern = (absolute[0] != 0) | (absolute[1] != 0) | (absolute[2] != 0)
    plan = _elimination_plan(pattern[:, :, 0])
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
            LU = P.copy()  # its factors, after the elimination
            Y = _eliminate_small(LU, rhs.copy(), plan)
            a = np.abs(sv)
            absolute_P = (absolute[0] * a + absolute[1]) * a + absolute[2]
            omega, spread = _small_residual(P, absolute_P, Y, rhs)
            bad = np.flatnonzero(~(omega <= BACKWARD))
            if len(bad):
                fixed = _refined_solve(*(np.moveaxis(v[:, :, bad], -1, 0) for v in (P, absolute_P, rhs)))
                Y[:, :, bad], omega[bad], spread[:, :, bad] = np.moveaxis(fixed[0], 0, -1), fixed[1], \
                    np.moveaxis(fixed[2], 0, -1)
            bound = _screen(_small_comparison_solve(LU, spread, plan), Y, lin, sv, omega)
            bound[:, :, bad] = np.inf
            H = np.zeros((len(lin.outputs), ni, len(sv)), dtype=complex)
            Yq = np.ascontiguousarray(Y[:n]).reshape(n, -1)  # (coordinate, input × frequency): one product a power
            for c in reversed(lin.Cq):  # Σ s^k Cq_k y, by Horner's rule
                H *= sv
                H += (c @ Yq).reshape(H.shape)
            _horner([d[:, :, None] for d in lin.D], sv, H, add=True)
            if inverse:
                H += lin.Di[:, :, None] / sv
            for f in _unvouched(bound, H):  # the adjoint Pᵀ w = c(s)ᵀ, by LAPACK, where the screen cannot vouch
                W = _refined_solve(P[:, :, f].T[None], absolute_P[:, :, f].T[None],
                                   _adjoint_rhs(lin, N, sv[f:f + 1])[:, :, 0][None])[0][0]
                bound[:, :, f] = _bound(spread[:, :, f:f + 1], W[:, :, None], Y[:, :, f:f + 1], lin, sv[f:f + 1],
                                        omega[f:f + 1])[:, :, 0]
        out[lo:lo + chunk] = np.moveaxis(H, -1, 0)
        bounds[lo:lo + chunk] = np.moveaxis(bound, -1, 0)
    return out, bounds


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
    else by blocks; ``A`` is left holding ``U`` and, below its diagonal, the factors of ``L`` (where ``plan``
    eliminated).  A zero pivot leaves ``inf`` or ``nan``, which the caller's check catches."""
    if plan is not None:
        steps, back = plan
        for k, rows, cols in steps:
            for i in rows:
                factor = A[i, k] / A[k, k]
                for j in cols:
                    A[i, j] -= factor * A[k, j]
                y[i] -= factor * y[k]
                A[i, k] = factor
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
        A[k + 1:, k] = factor
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            y[k] -= np.einsum("jf,jrf->rf", A[k, k + 1:], y[k + 1:])
        y[k] /= A[k, k]
    return y


def _small_residual(A: np.ndarray, absolute: np.ndarray, y: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(ratio, scale)``: per frequency ``max_i |A y − b|_i / scale_i`` (``nan`` where the solve broke down), with
    ``scale = absolute |y| + |b|`` (``absolute ≥ |A|``: ``|M| |s|² + |C| |s| + |K|``, as the error bound has it)."""
    with np.errstate(invalid="ignore", over="ignore"):
        r = np.abs(np.einsum("ijf,jrf->irf", A, y) - b)
        scale = np.einsum("ijf,jrf->irf", absolute, np.abs(y)) + np.abs(b)
        ratio = r / scale
    ratio[(scale == 0) & (r == 0)] = 0.0
    return ratio.reshape(-1, A.shape[-1]).max(axis=0), scale


def _small_comparison_solve(LU: np.ndarray, z: np.ndarray, plan: tuple[list, list] | None) -> np.ndarray:
    """``⟨U⟩⁻¹ ⟨L⟩⁻¹ z`` for factors held as :func:`_eliminate_small` leaves them and ``z ≥ 0`` (unknowns × columns
    × frequencies), ``⟨T⟩`` being ``T``'s comparison matrix (``|t_ii|`` on the diagonal, ``−|t_ij|`` off it): an
    upper bound of ``|P⁻¹| z``, as ``|P⁻¹| ≤ |U⁻¹| |L⁻¹| ≤ ⟨U⟩⁻¹ ⟨L⟩⁻¹``."""
    z = z.copy()
    A = np.abs(LU)
    N = len(A)
    steps = plan[0] if plan is not None else [(k, range(k + 1, N), range(k + 1, N)) for k in range(N - 1)]
    for k, rows, _ in steps:
        for i in rows:
            z[i] += A[i, k, None] * z[k]
    back = plan[1] if plan is not None else [(k, range(k + 1, N)) for k in range(N - 1, -1, -1)]
    for k, cols in back:
        for j in cols:
            z[k] += A[k, j, None] * z[j]
        z[k] /= A[k, k, None]
    return z


def _screen(z: np.ndarray, X: np.ndarray, lin: LinearModel, sv: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """An upper bound of :func:`_bound` from ``z ≥ |P⁻¹| (|P| |x| + |b|)`` (:func:`_small_comparison_solve`,
    :func:`_band_comparison_solve`): ``|c(s)| (z + |x|)`` times :func:`_factor`, ``(outputs, inputs,
    frequencies)``.  Where it is below the value's size, the value is certain and no adjoint solve is needed
    (:func:`_unvouched`)."""
    n = len(lin.coordinates)
    c_abs = sum(np.abs(c)[:, :, None] * np.abs(sv) ** k for k, c in enumerate(lin.Cq))
    with np.errstate(invalid="ignore", over="ignore"):
        return _factor(omega) * np.einsum("ojf,jrf->orf", c_abs, z[:n] + np.abs(X[:n]))


def _unvouched(bound: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The frequencies (last axis) where some finite value is not below its screened bound: those whose bound is
    computed exactly, by the adjoint solve."""
    with np.errstate(invalid="ignore"):
        return np.flatnonzero(np.any(np.isfinite(H) & ~(bound < np.abs(H)), axis=(0, 1)))


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


def _solve_banded(lin: LinearModel, svals: np.ndarray, perm: np.ndarray, lower: int,
                  upper: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_respond`'s ``H(s)`` and bounds by a banded LU without pivoting, run for a chunk of frequencies at once (:func:`_band_solve`), each
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
    abs_bands = [np.abs(b) for b in bands]
    out = np.empty((len(svals), len(lin.outputs), ni), dtype=complex)
    bounds = np.empty(out.shape)
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
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            rhs = np.zeros((N, ni, len(sv)), dtype=complex)
            _add_rows(B, sv, rhs)
            if np.any(Bi):
                rhs += Bi[:, :, None] / sv
            D = sum(d[None] * sv[:, None, None]**k for k, d in enumerate(lin.D)) + (
                lin.Di[None] / sv[:, None, None] if np.any(lin.Di) else 0)
            a = np.abs(sv)
            Y, spread, omega, factors, bad = _checked_band(A, rhs, lower, upper,
                                                           (abs_bands[0] * a + abs_bands[1]) * a + abs_bands[2])
            X, Z = np.empty_like(Y), np.empty(Y.shape)
            X[perm] = Y
            Z[perm] = _band_comparison_solve(A, factors, spread, lower, upper)
            bound = _screen(Z, X, lin, sv, omega)
            bound[:, :, bad] = np.inf
            Xq = X[:n].reshape(n, -1)  # (coordinate, input × frequency): the outputs by one matrix product a power
            H = sum((c @ Xq).reshape(len(c), ni, -1) * sv**k for k, c in enumerate(lin.Cq))
            for f in _unvouched(bound, H):  # the adjoint Pᵀ w = c(s)ᵀ, by gbsv, where the screen cannot vouch
                W = np.empty((N, len(lin.outputs), 1), dtype=complex)
                absolute_P = (abs_bands[0] * abs(sv[f]) + abs_bands[1]) * abs(sv[f]) + abs_bands[2]
                W[perm] = _gbsv_refined(_band_transposed(A[:, :, f:f + 1], lower, upper)[:, :, 0],
                                        _band_transposed(absolute_P, lower, upper)[:, :, 0],
                                        _adjoint_rhs(lin, N, sv[f:f + 1], order=perm)[:, :, 0], upper, lower)[0][:, :, None]
                Sf = np.empty((N, ni, 1))
                Sf[perm] = spread[:, :, f:f + 1]
                bound[:, :, f] = _bound(Sf, W, X[:, :, f:f + 1], lin, sv[f:f + 1], omega[f:f + 1])[:, :, 0]
        out[lo:lo + chunk] = np.moveaxis(H, -1, 0) + D
        bounds[lo:lo + chunk] = np.moveaxis(bound, -1, 0)
    return out, bounds


def _checked_band(A: np.ndarray, rhs: np.ndarray, lower: int, upper: int,
                  absolute: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, object, np.ndarray]:
    """``(y, spread, omega, factors, bad)``: :func:`_band_factor_solve`, a frequency whose backward error (against
    ``absolute``, :func:`_residual`) exceeds :data:`BACKWARD` solved again by ``gbsv`` and refined (listed in
    ``bad``: ``factors`` are not its factors), ``spread = |P| |y| + |b|`` and the backward errors ``omega``."""
    Y, factors = _band_factor_solve(A, rhs, lower, upper)
    with np.errstate(invalid="ignore", over="ignore"):
        omega, spread = _residual(A, Y, rhs, lower, absolute)
    bad = np.flatnonzero(~(omega <= BACKWARD))
    for f in bad:
        Y[:, :, f], omega[f], spread[:, :, f] = _gbsv_refined(A[:, :, f], absolute[:, :, f], rhs[:, :, f], lower, upper)
    return Y, spread, omega, factors, bad


def _gbsv_refined(A: np.ndarray, absolute: np.ndarray, b: np.ndarray, lower: int,
                  upper: int) -> tuple[np.ndarray, float, np.ndarray]:
    """``(y, omega, spread)`` of one frequency's band (``A[i, d]``, ``b[i, r]``) by :func:`_gbsv`, refined as
    :func:`_refined_solve` refines."""
    A, absolute, b = A[:, :, None], absolute[:, :, None], b[:, :, None]
    y = _gbsv(A[:, :, 0], b[:, :, 0], lower, upper)[:, :, None]
    for step in range(REFINE + 1):
        with np.errstate(invalid="ignore", over="ignore"):
            ratio, scale = _residual(A, y, b, lower, absolute)
        if ratio[0] <= BACKWARD or step == REFINE or not np.all(np.isfinite(y)):
            break
        y += _gbsv(A[:, :, 0], -_residual_vector(A, y, b, lower)[:, :, 0], lower, upper)[:, :, None]
    return y[:, :, 0], ratio[0], scale[:, :, 0]


def _residual_vector(A: np.ndarray, y: np.ndarray, b: np.ndarray, lower: int) -> np.ndarray:
    """``A y − b`` for a band ``A[i, d, f]``."""
    N, width = A.shape[0], A.shape[1]
    r = -b
    for d in range(width):
        j0, j1 = max(0, lower - d), min(N, N + lower - d)
        if j1 > j0:
            r[j0:j1] += A[j0:j1, d, None] * y[j0 + d - lower:j1 + d - lower]
    return r


def _band_comparison_solve(A: np.ndarray, factors: object, z: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """:func:`_small_comparison_solve` for a band's factors as :func:`_band_factor_solve` gives them: a tridiagonal
    system's pivots (its factors are ``A``'s sub-diagonal over them, its ``U`` the pivots and ``A``'s
    super-diagonal), else the band with ``L``'s factors below the diagonal and ``U`` on and above it."""
    z = z.copy()
    N = A.shape[0]
    if lower == upper == 1:
        pivots = np.abs(factors)
        off = np.abs(A[:, ::2])
        for i in range(1, N):
            z[i] += (off[i, 0] / pivots[i - 1])[None] * z[i - 1]
        z[N - 1] /= pivots[N - 1][None]
        for i in range(N - 2, -1, -1):
            z[i] += off[i, 1][None] * z[i + 1]
            z[i] /= pivots[i][None]
        return z
    LU = np.abs(factors)
    for k in range(N - 1):
        for i in range(k + 1, min(N, k + lower + 1)):
            z[i] += LU[i, k - i + lower, None] * z[k]
    for k in range(N - 1, -1, -1):
        for j in range(1, min(upper, N - 1 - k) + 1):
            z[k] += LU[k, lower + j, None] * z[k + j]
        z[k] /= LU[k, lower, None]
    return z


def _band_transposed(A: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """The band of the transposed matrices (bandwidths swapped): ``Aᵀ[i, d] = A[i + d − upper, lower + upper − d]``."""
    N, width = A.shape[0], A.shape[1]
    out = np.zeros_like(A)
    for d in range(width):
        j0, j1 = max(0, upper - d), min(N, N + upper - d)  # rows i whose source row i + d − upper exists
        if j1 > j0:
            out[j0:j1, d] = A[j0 + d - upper:j1 + d - upper, lower + upper - d]
    return out


def _padded_rows(mats: list, N: int, n: int) -> list[np.ndarray]:
    """Input matrices over the ``n`` coordinates, padded with zero rows to all ``N`` unknowns (the multipliers')."""
    out = []
    for m in mats:
        full = np.zeros((N, np.shape(m)[1]), dtype=complex)
        full[:n] = m
        out.append(full)
    return out


#: The largest componentwise backward error (``max |P y − b| / (|P| |y| + |b|)``, ``|P|`` being ``|M| |s|² + |C| |s|
#: + |K|``) a solve without pivoting may leave before the frequency is solved again with pivoting, and towards which
#: a solve with pivoting is refined (:func:`_refined_solve`): the error bound grows with it (:func:`_factor`).
#: Measured at 1,000 frequencies on a series RLC, a Butterworth ladder, a loudspeaker, coupled tanks and a
#: 100-section ladder: at most 1.4 ε without pivoting, so that no frequency there is solved again.
BACKWARD = 8 * np.finfo(float).eps


def _band_solve(A: np.ndarray, b: np.ndarray, lower: int, upper: int) -> np.ndarray:
    """Solve ``A y = b`` for banded matrices over a last axis of frequencies (``A[i, d, f] = A_f[i, i + d − lower]``,
    ``b[i, r, f]``) by Gaussian elimination without pivoting, every frequency at once: the loops run over the
    rows, NumPy over contiguous frequencies.  A zero pivot leaves ``inf`` or ``nan``, which the caller's residual
    check catches."""
    return _band_factor_solve(A, b, lower, upper)[0]


def _band_factor_solve(A: np.ndarray, b: np.ndarray, lower: int, upper: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_band_solve` and its factors: a tridiagonal system's pivots, else the band with ``L``'s factors
    below the diagonal and ``U`` on and above it (:func:`_band_comparison_solve` reads either)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if lower == upper == 1:
            return _tridiagonal(A, b.copy())
        LU = A.copy()
        return _eliminate(LU, b.copy(), lower, upper), LU


def _tridiagonal(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_eliminate` of a tridiagonal system (a ladder, a chain), ``A`` left as it is: only the pivots are
    new (``d``, returned with the solution), the sub-diagonal is read once for its factor and the super-diagonal is
    the eliminated rows' own."""
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
    return y, d


def _eliminate(A: np.ndarray, y: np.ndarray, lower: int, upper: int) -> np.ndarray:
    N = A.shape[0]
    for k in range(N - 1):
        pivot = A[k, lower]
        for i in range(k + 1, min(N, k + lower + 1)):
            d = k - i + lower  # row i, column k
            factor = A[i, d] / pivot
            A[i, d:d + upper + 1] -= factor * A[k, lower:]
            y[i] -= factor * y[k]
            A[i, d] = factor
    for k in range(N - 1, -1, -1):
        for j in range(1, min(upper, N - 1 - k) + 1):
            y[k] -= A[k, lower + j] * y[k + j]
        y[k] /= A[k, lower]
    return y


def _residual(A: np.ndarray, y: np.ndarray, b: np.ndarray, lower: int,
              absolute: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(ratio, scale)``: per frequency ``max_i |A y − b|_i / scale_i`` (``nan`` where the solve broke down), with
    ``scale = |P| |y| + |b|``, ``|P|`` being ``absolute`` (a band of ``|M| |s|² + |C| |s| + |K| ≥ |A|``: the
    backward error then measured against each coefficient matrix, as the error bound is) or ``|A|``."""
    N, width = A.shape[0], A.shape[1]
    r, scale = -b, np.abs(b)  # fresh arrays: b is not written
    y_abs = None if absolute is None else np.abs(y)
    for d in range(width):
        j0, j1 = max(0, lower - d), min(N, N + lower - d)  # rows whose column i + d − lower exists
        if j1 <= j0:
            continue
        term = A[j0:j1, d, None] * y[j0 + d - lower:j1 + d - lower]
        r[j0:j1] += term
        if absolute is None:
            scale[j0:j1] += np.abs(term)
        else:
            scale[j0:j1] += absolute[j0:j1, d, None] * y_abs[j0 + d - lower:j1 + d - lower]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.abs(r) / scale
    ratio[(scale == 0) & (r == 0)] = 0.0
    return ratio.reshape(-1, A.shape[-1]).max(axis=0), scale


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
