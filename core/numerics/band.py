"""Banded solves for large sparse systems: ``A u = b`` of a model of many coordinates, in time and memory linear in
its size.

A chain of 10⁴ masses has a mass matrix of 10⁴ nonzero entries among 10⁸: stored dense it takes 800 MB, and a
dense LU per evaluation is out of reach.  Its coordinates, renumbered by reverse Cuthill–McKee
(:func:`scipy.sparse.csgraph.reverse_cuthill_mckee` on the pattern of ``A + Aᵀ``), put every nonzero entry within
a band of ``kl`` diagonals below and ``ku`` above the main one; LU with partial pivoting then keeps its fill within
``kl`` more above (row interchanges), so a solve costs ``O(nm · kl · (kl + ku))`` operations and
``nm · (2 kl + ku + 1)`` numbers.  A tridiagonal chain is ``kl = ku = 1``; point masses on absolute coordinates
are diagonal, ``kl = ku = 0``.

:func:`plan` decides, once per model, from the pattern of the generic ``A`` (its structurally nonzero entries):
a band when the system has at least :data:`BAND_FROM` unknowns, no constraint rows (their multipliers' balancing is
the dense solve's), and a band at most an eighth of its size wide; else ``None`` (the dense solve).  The tape of
``A`` then records its nonzero entries only, in :attr:`Band.pattern`'s order, and the C functions here scatter them
into band storage and solve.  The pivoting rule and the singularity test are the dense solve's (a pivot below
``nm · ε · max|A|``), on the renumbered matrix.

>>> import sympy as sp
>>> x = sp.symbols("x0:200")
>>> A = sp.SparseMatrix(200, 200, {**{(i, i): 2 + x[i] ** 2 for i in range(200)},
...                                **{(i, i + 1): -1 for i in range(199)}, **{(i + 1, i): -1 for i in range(199)}})
>>> band = plan(A, constraints=0)
>>> (band.kl, band.ku, len(band.pattern))
(1, 1, 598)
>>> plan(A[:20, :20], constraints=0) is None   # (below BAND_FROM unknowns: the dense solve)
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: The fewest unknowns for which a banded solve is taken.  Measured (``benchmarks/band.py``, one evaluation on the
#: tape interpreter): a chain of masses (diagonal) takes 2.5 µs banded and 2.9 µs dense at 16 unknowns, 3.7 and
#: 5.7 µs at 32, 22 and 195 µs at 256; a capacitor ladder (tridiagonal) 2.6 and 4.4 µs at 32.
BAND_FROM = 32


@dataclass(frozen=True)
class Band:
    """A banded solve: ``pattern`` the nonzero entries ``(i, j)`` of ``A`` (the order the tape records them in),
    ``perm`` the renumbering (new index ``r`` is unknown ``perm[r]``), ``kl``/``ku`` the bandwidths after it,
    ``slot`` each pattern entry's place in the band storage (row ``r`` from column ``r − kl``, ``2 kl + ku + 1``
    numbers a row)."""

    nm: int
    pattern: tuple[tuple[int, int], ...]
    perm: np.ndarray
    kl: int
    ku: int
    slot: np.ndarray

    @property
    def width(self) -> int:
        return 2 * self.kl + self.ku + 1

    @property
    def rows(self) -> np.ndarray:
        return np.array([i for i, _ in self.pattern], dtype=np.int32)

    @property
    def cols(self) -> np.ndarray:
        return np.array([j for _, j in self.pattern], dtype=np.int32)


def plan(A, constraints: int) -> Band | None:
    """The banded solve of the (generic, symbolic) square matrix ``A`` with ``constraints`` multiplier rows, or
    ``None`` for the dense one (see the module's text)."""
    nm = A.rows
    if nm < BAND_FROM or constraints:
        return None
    pattern = tuple(sorted(A.todok()))
    if not pattern:
        return None
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    rows = np.fromiter((i for i, _ in pattern), dtype=np.int64, count=len(pattern))
    cols = np.fromiter((j for _, j in pattern), dtype=np.int64, count=len(pattern))
    ones = np.ones(2 * len(pattern) + nm)
    every = np.arange(nm)
    symmetric = coo_matrix((ones, (np.concatenate([rows, cols, every]), np.concatenate([cols, rows, every]))),
                           shape=(nm, nm)).tocsr()
    perm = np.asarray(reverse_cuthill_mckee(symmetric, symmetric_mode=True), dtype=np.int32)
    inv = np.empty(nm, dtype=np.int64)
    inv[perm] = np.arange(nm)
    r, c = inv[rows], inv[cols]
    kl, ku = int(max(0, np.max(r - c))), int(max(0, np.max(c - r)))
    width = 2 * kl + ku + 1
    if 8 * width > nm:
        return None
    slot = (r * width + (c - r + kl)).astype(np.int64)
    if slot.max() >= np.iinfo(np.int32).max:  # (beyond a C int's index: the dense solve refuses such sizes anyway)
        return None
    return Band(nm, pattern, perm, kl, ku, slot.astype(np.int32))


def solve_size(eq) -> int:
    """The number of unknowns of ``eq``'s solve ``A u = b``."""
    if eq.recursion is not None:  # (the accelerations, then the constraints' multipliers)
        return len(eq.names) + len(eq.recursion.multipliers)
    return int(math.isqrt(len(eq.generic()["A"])))


def recursive_arrays(eq) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    """A recursion's arrays (:mod:`lagrangian.derivation.recursion`): ``A`` the identity by its diagonal (the
    :func:`band_of` of a recursion), ``b`` the accelerations and the constraints' multipliers, and the energies with its kinetic energy and momenta."""
    rec, g = eq.recursion.recursion, eq.generic()
    T, V, D = rec.kinetic, g["V"], g["D"]
    u = [*rec.accelerations, *eq.recursion.multipliers]
    return [sp.S.One] * len(u), u, [T, V, D, T - V, *rec.momenta]


def band_of(eq) -> Band | None:
    """The banded solve of ``eq``'s ``A u = b`` (:mod:`lagrangian.numerics.band`), or ``None`` for the dense one;
    decided once per model (a recursion's ``A`` is the identity: a band of no diagonals beside the main one)."""
    if "_band" not in eq.__dict__ and eq.recursion is not None:
        n = solve_size(eq)
        every = np.arange(n, dtype=np.int32)
        eq.__dict__["_band"] = Band(n, tuple((i, i) for i in range(n)), every, 0, 0, every.copy())
    if "_band" not in eq.__dict__:
        g = eq.generic()
        eq.__dict__["_band"] = plan(g["A"], constraints=g["A"].rows - len(eq.inertial) - len(eq.first_order))
    return eq.__dict__["_band"]


# The solve in C: in the runtime library (sizes as arguments) and in a native library.
BAND_SOLVE = r"""
/* LU with partial pivoting of a band matrix, in place, x (nm) becoming the solution: row r holds columns r - kl to
   r + kl + ku from B[r * W] (W = 2 kl + ku + 1: row interchanges widen the upper band by kl).  The dense solve's
   rules: 0 solved, 1 singular (a pivot not above nm eps max|A|), 2 not finite. */
static int band_core(int nm, int kl, int ku, double *B, double *x) {
    const long W = 2L * kl + ku + 1;
    const int up = kl + ku;
    double amax = 0.0;
    for (long i = 0; i < (long)nm * W; i++) { const double a = fabs(B[i]); if (!(a <= DBL_MAX)) return 2; if (a > amax) amax = a; }
    const double tiny = nm * DBL_EPSILON * amax;
    if (nm && !(amax > 0.0)) return 1;
#define AT(r, c) B[(long)(r) * W + ((c) - (r) + kl)]
    for (int k = 0; k < nm; k++) {
        const int last = k + kl < nm - 1 ? k + kl : nm - 1, right = k + up < nm - 1 ? k + up : nm - 1;
        int p = k;
        double best = fabs(AT(k, k));
        for (int i = k + 1; i <= last; i++) { const double a = fabs(AT(i, k)); if (a > best) { best = a; p = i; } }
        if (!(best > tiny)) return best == best ? 1 : 2;
        if (p != k) {
            for (int j = k; j <= right; j++) { const double s = AT(k, j); AT(k, j) = AT(p, j); AT(p, j) = s; }
            const double s = x[k]; x[k] = x[p]; x[p] = s;
        }
        const double inv = 1.0 / AT(k, k);
        for (int i = k + 1; i <= last; i++) {
            const double f = AT(i, k) * inv;
            if (f != 0.0) {
                for (int j = k + 1; j <= right; j++) AT(i, j) -= f * AT(k, j);
                x[i] -= f * x[k];
            }
        }
    }
    for (int k = nm - 1; k >= 0; k--) {
        const int right = k + up < nm - 1 ? k + up : nm - 1;
        double s = x[k];
        for (int j = k + 1; j <= right; j++) s -= AT(k, j) * x[j];
        x[k] = s / AT(k, k);
    }
#undef AT
    return 0;
}

/* A u = b, A given by its nonzero entries vals[nnz] at band places slot[] (unknowns renumbered: new r is old
   perm[r]); B (nm W) and x (nm) scratch, u (nm) the solution. */
static int band_solve(int nm, int kl, int ku, int nnz, const int *slot, const int *perm, const double *vals,
                      const double *b, double *B, double *x, double *u) {
    const long W = 2L * kl + ku + 1;
    memset(B, 0, sizeof(double) * (size_t)nm * W);
    for (int k = 0; k < nnz; k++) B[slot[k]] = vals[k];
    for (int r = 0; r < nm; r++) x[r] = b[perm[r]];
    const int rc = band_core(nm, kl, ku, B, x);
    if (!rc) for (int r = 0; r < nm; r++) u[perm[r]] = x[r];
    return rc;
}
"""

# The runtime library's banded model: its tape (lg_tape, first, so that the tape's energies take it as it is) and
# its band.
BAND_RUNTIME = r"""
typedef struct { lg_tape tape; int kl, ku, nnz; const int *slot, *perm, *row, *col; } lg_band;

int lg_band_rhs(const void *ctx, double t, const double *y, double *dy) {
    const lg_band *m = ctx;
    const long nm = m->tape.nm, W = 2L * m->kl + m->ku + 1;
    SCRATCH(o, m->nnz + nm + nm * W + 2 * nm + 1);
    if (!o) return 2;
    double *B = o + m->nnz + nm, *x = B + nm * W, *u = x + nm;
    int rc = run_on(&m->tape.matrix, t, y, m->tape.nq, y + m->tape.nq, m->tape.ni, o);
    if (!rc) rc = band_solve(nm, m->kl, m->ku, m->nnz, m->slot, m->perm, o, o + m->nnz, B, x, u);
    if (!rc) rc = state_rate(m->tape.nq, m->tape.ni, m->tape.nf, m->tape.inertial, m->tape.first, y, u, dy);
    RELEASE(o);
    return rc;
}

int lg_band_matrix(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {
    const lg_band *m = ctx;
    const long nm = m->tape.nm;
    SCRATCH(o, m->nnz + nm + 1);
    if (!o) return 2;
    int rc = run_on(&m->tape.matrix, t, q, m->tape.nq, vI, m->tape.ni, o);
    memset(A, 0, sizeof(double) * nm * nm);
    for (int k = 0; k < m->nnz; k++) A[(long)m->row[k] * nm + m->col[k]] = o[k];
    memcpy(b, o + m->nnz, nm * sizeof(double));
    RELEASE(o);
    return rc;
}
"""


def native_tables(band: Band, table) -> list[str]:
    """A banded native library's sizes and tables, and the solve (``table`` spells a C array's initializer)."""
    return [f"#define KL {band.kl}", f"#define KU {band.ku}", f"#define NNZ {len(band.pattern)}",
            f"#define BW {band.width}", f"static const int SLOT[] = {table(band.slot.tolist())};",
            f"static const int PERM[] = {table(band.perm.tolist())};",
            f"static const int ROW[] = {table(band.rows.tolist())};",
            f"static const int COL[] = {table(band.cols.tolist())};", BAND_SOLVE]


# A banded native library's A, whole (for messages and checks; runs use the band).
BAND_MATRIX = ["int lg_matrix(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {",
               "    SCRATCH(V, NNZ + 1);",
               "    if (!V) return 2;",
               "    matrix_terms(ctx, t, q, vI, V, b);",
               "    memset(A, 0, sizeof(double) * NM * NM);",
               "    for (int k = 0; k < NNZ; k++) A[(long)ROW[k] * NM + COL[k]] = V[k];",
               "    RELEASE(V);",
               "    return 0;",
               "}"]

# A banded native library's state derivative.
NATIVE_BAND_RHS = r"""
int lg_rhs(const void *ctx, double t, const double *y, double *dy) {
    SCRATCH(V, NNZ + NM + (long)NM * BW + 2 * NM + 1);
    if (!V) return 2;
    double *b = V + NNZ, *B = b + NM, *x = B + (long)NM * BW, *u = x + NM;
    matrix_terms(ctx, t, y, y + NQ, V, b);
    int rc = band_solve(NM, KL, KU, NNZ, SLOT, PERM, V, b, B, x, u);
    if (!rc) rc = state_rate(NQ, NI, NF, INERTIAL, FIRST, y, u, dy);
    RELEASE(V);
    return rc;
}
"""
