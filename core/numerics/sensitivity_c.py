"""The augmented right-hand side of a sensitivity run in C (:mod:`lagrangian.numerics.sensitivity`): the tapes of
``A`` and ``b`` and of ``G`` run on the tape interpreter, one LU factorization of ``A`` per evaluation serving the
state and every sensitivity.  The library is compiled once per machine (cached as the runtime library is) and
loaded once per process."""

from __future__ import annotations

import ctypes
import os
import threading

import numpy as np

from .c_build import _cache, _key, _libraries, cache_dir, compiler, wanted_compiler
from .c_source import _HEADER, _SOLVE, _interpreter, _Unavailable, programs
from .codegen import _array, _prog, _Prog
from .simulation import NumericModel
from .tape import Program


_C_SENS = r"""
/* A sensitivity run: the tapes of A and b (from t, q, q'_I) and of G (from t, q, q'_I, u), the columns of G that are
   the parameters' (pcol[s], or -1 for an initial value) and the scales of their terms. */
typedef struct {
    int nq, ni, nf, nm, ns, ncol;
    const int *inertial, *first, *pcol;
    const double *pscale;
    lg_prog matrix, sens;
} lg_sens;

/* LU with partial pivoting in place (whole rows swapped, piv[k] the row brought to k); the singularity rule of
   lu_core. 0: factored, 1: singular, 2: not finite. */
static int sens_factor(int nm, double *A, int *piv) {
    double amax = 0.0;
    for (int i = 0; i < nm * nm; i++) {
        const double a = fabs(A[i]);
        if (!(a <= DBL_MAX)) return 2;
        if (a > amax) amax = a;
    }
    const double tiny = nm * DBL_EPSILON * amax;
    if (nm && !(amax > 0.0)) return 1;
    for (int k = 0; k < nm; k++) {
        int p = k;
        double best = fabs(A[k * nm + k]);
        for (int i = k + 1; i < nm; i++) { const double a = fabs(A[i * nm + k]); if (a > best) { best = a; p = i; } }
        if (!(best > tiny)) return best == best ? 1 : 2;
        piv[k] = p;
        if (p != k)
            for (int j = 0; j < nm; j++) { const double s = A[k * nm + j]; A[k * nm + j] = A[p * nm + j]; A[p * nm + j] = s; }
        const double inv = 1.0 / A[k * nm + k];
        for (int i = k + 1; i < nm; i++) {
            const double f = A[i * nm + k] * inv;
            A[i * nm + k] = f;
            if (f != 0.0) for (int j = k + 1; j < nm; j++) A[i * nm + j] -= f * A[k * nm + j];
        }
    }
    return 0;
}

/* x = A^-1 x from sens_factor's LU and pivots. */
static void sens_solve(int nm, const double *LU, const int *piv, double *x) {
    for (int k = 0; k < nm; k++) if (piv[k] != k) { const double s = x[k]; x[k] = x[piv[k]]; x[piv[k]] = s; }
    for (int i = 1; i < nm; i++) { double s = x[i]; for (int j = 0; j < i; j++) s -= LU[i * nm + j] * x[j]; x[i] = s; }
    for (int i = nm - 1; i >= 0; i--) {
        double s = x[i];
        for (int j = i + 1; j < nm; j++) s -= LU[i * nm + j] * x[j];
        x[i] = s / LU[i * nm + i];
    }
}

/* The augmented system: y = (q, q'_I, S_0, S_1, ...), each S_s of the state's length. 0, 1 singular, 2 not finite. */
int lg_sens_rhs(const void *ctx, double t, const double *y, double *dy) {
    const lg_sens *m = ctx;
    const int nq = m->nq, ni = m->ni, nf = m->nf, nm = m->nm, ns = m->ns, ncol = m->ncol, dim = nq + ni;
    SCRATCH(w, (long)nm * nm + 2 * nm + 1 + (long)nm * ncol);
    int piv_stack[256];
    int *piv = nm <= 256 ? piv_stack : malloc((size_t)nm * sizeof(int));
    int rc = (w && piv) ? 0 : 2;
    double *A = w, *u = w + (long)nm * nm, *R = u + nm, *G = R + nm + 1;
    if (!rc) rc = run_on(&m->matrix, t, y, nq, y + nq, ni, A);  /* A, then b in u */
    if (!rc) rc = sens_factor(nm, A, piv);
    if (!rc) { sens_solve(nm, A, piv, u); rc = state_rate(nq, ni, nf, m->inertial, m->first, y, u, dy); }
    if (!rc) rc = run_on(&m->sens, t, y, dim, u, nm, G);
    for (int s = 0; s < ns && !rc; s++) {
        const double *S = y + (long)dim * (1 + s);
        double *dS = dy + (long)dim * (1 + s);
        const int pc = m->pcol[s];
        for (int r = 0; r < nm; r++) {
            const double *g = G + (long)r * ncol;
            double acc = pc >= 0 ? m->pscale[s] * g[pc] : 0.0;
            for (int j = 0; j < dim; j++) acc += g[j] * S[j];
            R[r] = acc;
        }
        sens_solve(nm, A, piv, R);
        for (int j = 0; j < ni; j++) { dS[m->inertial[j]] = S[nq + j]; dS[nq + j] = R[j]; }
        for (int k = 0; k < nf; k++) dS[m->first[k]] = R[ni + k];
        for (int i = 0; i < dim; i++) if (!isfinite(dS[i])) { rc = 2; break; }
    }
    if (piv && piv != piv_stack) free(piv);
    if (w) RELEASE(w);
    return rc;
}
"""


def _source() -> str:
    return "\n".join(["/* lagrangian.numerics.sensitivity: the augmented right-hand side of a sensitivity run, on the tape "
                      "interpreter; do not edit. */", _HEADER, _SOLVE, _interpreter(), _C_SENS])


_LIBRARIES: dict[tuple[str, str], ctypes.CDLL] = {}
_LOCK = threading.Lock()


def _library() -> ctypes.CDLL:
    """The library of ``lg_sens_rhs``: from this process, the disk cache, or compiled now (once per machine);
    raises ``_Unavailable`` (or ``OSError``) when it cannot be had."""
    where = _where()
    lib = _LAST.get(where)
    if lib is not None:
        return lib
    cc = compiler()
    if cc is None:
        raise _Unavailable("no C compiler found")
    source = _source()
    directory, _ = _cache()
    key = _key(source, cc)
    with _LOCK:
        lib = _LIBRARIES.get((str(directory), key))
        if lib is None:
            lib = _libraries(directory, {"sensitivity": (key, source)}, cc)["sensitivity"].lib
            lib.lg_sens_rhs.argtypes = [ctypes.c_void_p, ctypes.c_double, ctypes.c_void_p, ctypes.c_void_p]
            lib.lg_sens_rhs.restype = ctypes.c_int
            _LIBRARIES[(str(directory), key)] = lib
        _LAST.clear()
        _LAST[where] = lib
    return lib


#: The library last loaded, by what chose it (:func:`_where`): a run of a fit (a run per trial point) finds it
#: without looking for the compiler on the PATH, checking the cache directory and hashing the source again.
_LAST: dict[tuple, ctypes.CDLL] = {}


def _where() -> tuple:
    """What decides which compiler and cache directory :func:`_library` uses (settings and environment)."""
    return (wanted_compiler(), os.environ.get("PATH"), cache_dir())


class _Sens(ctypes.Structure):
    _fields_ = [("nq", ctypes.c_int), ("ni", ctypes.c_int), ("nf", ctypes.c_int), ("nm", ctypes.c_int),
                ("ns", ctypes.c_int), ("ncol", ctypes.c_int), ("inertial", ctypes.c_void_p), ("first", ctypes.c_void_p),
                ("pcol", ctypes.c_void_p), ("pscale", ctypes.c_void_p), ("matrix", _Prog), ("sens", _Prog)]


class _Compiled:
    """The augmented right-hand side in C for one run's values: the context ``lg_sens_rhs`` reads (kept alive with
    the arrays it points into) and the function's address, for the runtime library's loops."""

    def __init__(self, lib: ctypes.CDLL, numeric: NumericModel, layout, sens: Program):
        matrix, _ = programs(numeric, banded=False)  # (the solve here is dense)
        keep: list = []
        L = layout
        self.struct = _Sens(L.n, L.nI, len(L.first), L.m, L.ns, L.ncol, _array(L.inertial, np.int32, keep),
                            _array(L.first, np.int32, keep), _array(L.pcol, np.int32, keep),
                            _array(L.pscale, np.float64, keep), _prog(matrix, keep), _prog(sens, keep))
        self.keep, self.layout, self.lib = keep, layout, lib
        self.ctx = ctypes.addressof(self.struct)
        self.ptr = ctypes.cast(lib.lg_sens_rhs, ctypes.c_void_p).value

    def __call__(self, t: float, Y: np.ndarray) -> tuple[int, np.ndarray]:
        """``(status, dY)`` at one augmented state (status 0: fine, 1: singular, 2: not finite)."""
        Y = np.ascontiguousarray(Y, dtype=float)
        dY = np.empty_like(Y)
        return self.lib.lg_sens_rhs(self.ctx, float(t), Y.ctypes.data, dY.ctypes.data), dY


