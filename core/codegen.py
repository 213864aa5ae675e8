"""Compiled models: C code for the right-hand side, built once and cached on disk.

:func:`compile_model` turns a :class:`~lagrangian.simulation.NumericModel`
into C: the entries of ``A(t, q, q̇)`` and ``b(t, q, q̇)`` of the solve
``A u = b`` (see :mod:`lagrangian.equations`) with common subexpressions
eliminated (:func:`sympy.cse`, SymPy's C99 printer), the solve itself done
in C by a small dense LU factorization with partial pivoting (``M⁻¹`` is
never formed symbolically), so that one call of ``lg_rhs`` gives the
derivative of the state ``(q, q̇_inertial)``; the energies ``T``, ``V``,
``D`` and the Jacobi integral; and stepping loops in C — an adaptive Dormand–Prince 5(4) pair
with dense output, classical Runge–Kutta and Störmer–Verlet — which the
integrators ``dopri5_c``, ``rk4_c`` and ``verlet_c`` (registered by the
built-in integrators plugin) run without returning to Python per step.

The system C compiler (``cc``, ``gcc`` or ``clang``; :func:`set_compiler`
or the environment variable ``LAGRANGIAN_CC`` choose another) builds a
shared library (``-O2 -shared -fPIC``) loaded with :mod:`ctypes`: no
dependency beyond a C compiler.  Two libraries in fact, compiled at the
same time: the model's own functions, and the stepping loops, which are
the same for every model (they call the model's ``lg_rhs`` through a
function pointer) and so are compiled once per compiler.  Libraries are
cached on disk, keyed by a hash of the generated source (which holds the
model's expressions with its numeric parameter values), the compiler and
its flags, so that the same model starts at once the second time.

Measured on the planar n-link pendulum (``benchmarks/rhs.py``): one
evaluation takes 0.07–0.5 µs in C for n = 3–10 (a hand-written C function
of the same system with the same LU takes as long) and 1–2.5 µs called
from Python; generating and compiling takes 0.2–0.6 s.  The cache lives in
``$LAGRANGIAN_CACHE_DIR``, else ``$XDG_CACHE_HOME/lagrangian``, else
``~/.cache/lagrangian`` (:func:`cache_dir`, :func:`set_cache_dir`); it is
safe to delete at any time — a missing or corrupt entry is rebuilt, and
entries are written to a temporary file and renamed, so that two processes
never see half a library.

When no compiler is found, compilation fails, or the model uses a time
signal given as a Python callable (which C cannot call), nothing crashes:
:func:`compile_model` returns ``None`` with the reason, which
``Model.simulate`` logs and puts in ``Result.notes`` before using the NumPy
path.  A singular matrix met in C raises
:class:`~lagrangian.SingularMassMatrixError`, a non-finite derivative
:class:`~lagrangian.NumericalError`.

>>> import tempfile, lagrangian as lg
>>> set_cache_dir(tempfile.mkdtemp())          # a private cache for this example
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=2)
>>> _ = m.add("spring", "k", ("ground", "p"), k=8)
>>> compiled, note = compile_model(m.numeric())  # (None, why) without a C compiler
>>> rhs = compiled.rhs if compiled is not None else m.numeric().rhs
>>> rhs(0.0, np.array([1.0, 0.5]))                # (q̇, q̈ = −k q / m)
array([ 0.5, -4. ])
>>> res = m.simulate(1.0, initial={"x_p": 1}, velocity={"x_p": 0}, method="dopri5_c", rtol=1e-10, points=3)
>>> bool(abs(res["x_p"][-1] - np.cos(2.0)) < 1e-8)
True
>>> set_cache_dir(None)
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import json
import logging
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef
from sympy.printing.c import C99CodePrinter

from .component import t as time_symbol
from .errors import ModelError, NumericalError, SingularMassMatrixError
from .integrate import FixedStepIntegrator, Integrator, Solution, _grid

__all__ = [
    "CompiledModel",
    "compile_model",
    "generate_source",
    "cache_dir",
    "set_cache_dir",
    "compiler",
    "set_compiler",
    "FLAGS",
    "CompiledDormandPrince",
    "CompiledFixedStep",
]

_log = logging.getLogger("lagrangian")

#: Flags of every compilation (part of the cache key).
FLAGS = ("-O2", "-shared", "-fPIC")
#: Bumped whenever the generated C changes shape, so that old cache entries are not reused.
CODEGEN_VERSION = "1"
_DIVERGED = 1e30
_settings: dict[str, Any] = {"cache_dir": None, "compiler": None}


class _Unavailable(Exception):
    """The model cannot be compiled here; the message says why (turned into a note, never raised to the user)."""


# ---------------------------------------------------------------------------
# Where: the cache and the compiler
# ---------------------------------------------------------------------------


def cache_dir() -> Path:
    """The directory of compiled artefacts: :func:`set_cache_dir`'s, else ``$LAGRANGIAN_CACHE_DIR``,
    else ``$XDG_CACHE_HOME/lagrangian``, else ``~/.cache/lagrangian``.  Safe to delete.

    >>> set_cache_dir("/tmp/lagrangian-doc-cache"); str(cache_dir())
    '/tmp/lagrangian-doc-cache'
    >>> set_cache_dir(None)
    """
    if _settings["cache_dir"] is not None:
        return Path(_settings["cache_dir"])
    env = os.environ.get("LAGRANGIAN_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "lagrangian"


def set_cache_dir(path: str | os.PathLike | None) -> None:
    """Use ``path`` for compiled artefacts from now on (``None``: back to the environment and defaults)."""
    _settings["cache_dir"] = None if path is None else os.fspath(path)


def set_compiler(command: str | None) -> None:
    """Compile with ``command`` (a program name or path) from now on; ``None``: back to the default.

    The default is ``$LAGRANGIAN_CC``, else the first of ``cc``, ``gcc``,
    ``clang`` on the ``PATH``.  A program that does not exist means "no
    compiler": models then run on the NumPy path, with a note.
    """
    _settings["compiler"] = command


def compiler() -> str | None:
    """The full path of the C compiler that would be used, or ``None`` if there is none."""
    chosen = _settings["compiler"] or os.environ.get("LAGRANGIAN_CC")
    if chosen:
        return shutil.which(chosen)
    for name in ("cc", "gcc", "clang"):
        found = shutil.which(name)
        if found:
            return found
    return None


@functools.lru_cache(maxsize=8)
def _compiler_identity(path: str) -> str:
    try:
        out = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=30, check=False)
        return (out.stdout or out.stderr).splitlines()[0] if (out.stdout or out.stderr) else path
    except (OSError, subprocess.SubprocessError):
        return path


# ---------------------------------------------------------------------------
# What: the C source
# ---------------------------------------------------------------------------


class _Printer(C99CodePrinter):
    """SymPy's C99 printer, with small integer powers as products (``pow`` is slow and not always inlined),
    the model's symbols printed as C array elements (``names``), and terms left in SymPy's order."""

    def __init__(self, names: dict | None = None):
        super().__init__({"order": "none"})
        self.names = {} if names is None else names

    def _print_Symbol(self, expr):
        name = self.names.get(expr)
        return name if name is not None else super()._print_Symbol(expr)

    def _print_Pow(self, expr):
        base, exp = expr.as_base_exp()
        if exp.is_Integer and 2 <= abs(int(exp)) <= 6:
            b = self.parenthesize(base, 1000)  # always wrapped
            prod = "*".join([f"({self._print(base)})" if not base.is_Atom else b] * abs(int(exp)))
            return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
        return super()._print_Pow(expr)


def _c_block(exprs: list[sp.Expr], targets: list[str], names: dict, indent: str = "    ") -> list[str]:
    """C statements assigning ``exprs`` to ``targets``, with common subexpressions in temporaries; ``names``
    maps the model's symbols to their C spelling (``q[0]``, ...)."""
    printer = _Printer(names)
    temps, reduced = sp.cse([sp.sympify(e) for e in exprs], symbols=sp.numbered_symbols("w"))
    lines = [f"{indent}const double {printer.doprint(s)} = {printer.doprint(e)};" for s, e in temps]
    lines += [f"{indent}{target} = {printer.doprint(e)};" for target, e in zip(targets, reduced)]
    if printer._not_supported:
        what = ", ".join(sorted({type(e).__name__ for e in printer._not_supported}))
        raise _Unavailable(f"the equations use functions the C printer does not know ({what})")
    return lines


def _arrays(numeric) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    """The entries of ``A`` and ``b``, and ``T, V, D, L`` and the momenta ``p = ∂L/∂q̇`` (for the Jacobi integral
    ``h = p·q̇ − L``), with the parameter values substituted."""
    eq = numeric.eq
    a_entries, b_entries = numeric._flat_exprs[0], numeric._flat_exprs[1]
    subs = {s: sp.Float(v) for s, v in numeric.values.items()}
    energies = [e.xreplace(subs) for e in (eq.T, eq.V, eq.D, eq.L, *eq.p)]
    return a_entries, b_entries, energies


def generate_source(numeric) -> str:
    """The C source of ``numeric``'s library (a :class:`~lagrangian.simulation.NumericModel`): ``lg_matrix``
    (the entries of ``A`` and ``b``), ``lg_rhs`` (that and the LU solve: the state derivative) and
    ``lg_energies`` (``T``, ``V``, ``D``, Jacobi integral); the stepping loops are a library of their own.

    Raises an internal error (turned into a note by :func:`compile_model`)
    when the model cannot be compiled: time signals given as Python
    callables, or functions the C printer does not know.
    """
    eq = numeric.eq
    a_entries, b_entries, energies = _arrays(numeric)
    callables = sorted({f.func.__name__ for e in [*a_entries, *b_entries, *energies] for f in sp.sympify(e).atoms(AppliedUndef)})
    if callables or any(sp.sympify(e).has(sp.Derivative) for e in [*a_entries, *b_entries]):
        raise _Unavailable(
            f"the model uses time signal(s) given as Python callables ({', '.join(callables) or 'derivatives'}), "
            f"which compiled code cannot call; give them as SymPy expressions of t to compile"
        )
    n, nI = numeric.n, numeric.nI
    first = list(eq.first_order)
    m = int(math.isqrt(len(a_entries)))
    q, v = eq.sym.q, eq.sym.v
    cq = {s: f"q[{i}]" for i, s in enumerate(q)}
    cvI = {v[i]: f"vI[{j}]" for j, i in enumerate(eq.inertial)}
    cv = {s: f"v[{i}]" for i, s in enumerate(v)}
    ct = {time_symbol: "t"}
    matrix = _c_block(a_entries + b_entries, [f"A[{k}]" for k in range(m * m)] + [f"b[{k}]" for k in range(m)],
                      {**cq, **cvI, **ct})
    energy = _c_block(energies, ["out[0]", "out[1]", "out[2]", "L"] + [f"p[{i}]" for i in range(n)], {**cq, **cv, **ct})

    def table(values):
        return "{" + ", ".join(map(str, values or [0])) + "}"

    coordinates = ", ".join(numeric.eq.names).replace("*/", "* /")
    header = f"""/* Generated by lagrangian.codegen {CODEGEN_VERSION}; coordinates {coordinates}; do not edit. */
#include <math.h>
#include <float.h>
#include <string.h>

#define NQ {n}
#define NI {nI}
#define NF {len(first)}
#define NM {m}
#define DIM {n + nI}
static const int INERTIAL[] = {table(eq.inertial)};
static const int FIRST[] = {table(first)};
"""
    body = [
        "int lg_dims(int *out) { out[0] = NQ; out[1] = NI; out[2] = NM; out[3] = NF; return 0; }",
        "",
        "/* The entries of A (row-major, NM x NM) and b of the solve A u = b, u = (accelerations, first-order rates, multipliers). */",
        "void lg_matrix(double t, const double *q, const double *vI, double *A, double *b) {",
        *matrix,
        "}",
        "",
        "/* T, V, D and the Jacobi integral h at (t, q, v), v: the rates of all coordinates. */",
        "static void energy1(double t, const double *q, const double *v, double *out) {",
        "    double L, p[NQ];",
        *energy,
        "    double h = -L;",
        "    for (int i = 0; i < NQ; i++) h += v[i] * p[i];",
        "    out[3] = h;",
        "}",
        "",
        _RUNTIME,
    ]
    return header + "\n".join(body) + "\n"


# The solve and the state derivative (compiled with the model, whose sizes are then constants).
_RUNTIME = r"""
void lg_energies(long N, const double *t, const double *q, const double *v, double *out) {
    for (long k = 0; k < N; k++) energy1(t[k], q + k * NQ, v + k * NQ, out + 4 * k);
}

/* LU with partial pivoting, in place; b becomes the solution. 0: solved, 1: singular, 2: not finite. */
static int lu_solve(double *A, double *b) {
    double amax = 0.0;
    for (int i = 0; i < NM * NM; i++) {
        double a = fabs(A[i]);
        if (!(a <= DBL_MAX)) return 2;
        if (a > amax) amax = a;
    }
    const double tiny = NM * DBL_EPSILON * amax;
    if (!(amax > 0.0)) return 1;
    for (int k = 0; k < NM; k++) {
        int p = k;
        double best = fabs(A[k * NM + k]);
        for (int i = k + 1; i < NM; i++) {
            double a = fabs(A[i * NM + k]);
            if (a > best) { best = a; p = i; }
        }
        if (!(best > tiny)) return best == best ? 1 : 2;
        if (p != k) {
            for (int j = k; j < NM; j++) { double s = A[k * NM + j]; A[k * NM + j] = A[p * NM + j]; A[p * NM + j] = s; }
            double s = b[k]; b[k] = b[p]; b[p] = s;
        }
        const double inv = 1.0 / A[k * NM + k];
        for (int i = k + 1; i < NM; i++) {
            const double f = A[i * NM + k] * inv;
            if (f != 0.0) {
                for (int j = k + 1; j < NM; j++) A[i * NM + j] -= f * A[k * NM + j];
                b[i] -= f * b[k];
            }
        }
    }
    for (int k = NM - 1; k >= 0; k--) {
        double s = b[k];
        for (int j = k + 1; j < NM; j++) s -= A[k * NM + j] * b[j];
        b[k] = s / A[k * NM + k];
    }
    return 0;
}

/* dy/dt at (t, y), y = (q, q'_inertial). 0: fine, 1: singular matrix, 2: not finite. */
int lg_rhs(double t, const double *y, double *dy) {
    double A[NM * NM], b[NM];
    const double *q = y, *vI = y + NQ;
    lg_matrix(t, q, vI, A, b);
    int rc = lu_solve(A, b);
    if (rc) return rc;
    for (int j = 0; j < NI; j++) { dy[INERTIAL[j]] = vI[j]; dy[NQ + j] = b[j]; }
    for (int j = 0; j < NF; j++) dy[FIRST[j]] = b[NI + j];
    for (int i = 0; i < DIM; i++) if (!isfinite(dy[i])) return 2;
    return 0;
}

"""


# The stepping loops: compiled once per compiler into a library of their own (model-independent), so that
# a model compiles only its own functions.
_LOOPS = r"""
/* lagrangian.codegen: the stepping loops, the same for every model; they call the model's lg_rhs through f. */
#include <math.h>
#include <float.h>
#include <string.h>

typedef int (*rhs_fn)(double t, const double *y, double *dy);

/* All rates v (length nq) at many states (rows of Y, N x dim). Returns -1 or the index of the first failure. */
long lg_velocities(rhs_fn f, int nq, int dim, long N, const double *t, const double *Y, double *V) {
    double dy[dim];
    for (long k = 0; k < N; k++) {
        if (f(t[k], Y + k * dim, dy)) return k;
        memcpy(V + k * nq, dy, nq * sizeof(double));
    }
    return -1;
}

static int bounded(int dim, const double *y, double limit) {
    for (int i = 0; i < dim; i++) if (!(fabs(y[i]) < limit)) return 0;
    return 1;
}

static double rms_scaled(int dim, const double *x, const double *scale) {
    double s = 0.0;
    for (int i = 0; i < dim; i++) { double r = x[i] / scale[i]; s += r * r; }
    return dim ? sqrt(s / dim) : 0.0;
}

static void fail_at(int dim, double *fail, double t, const double *y) { fail[0] = t; memcpy(fail + 1, y, dim * sizeof(double)); }

/* Dormand-Prince 5(4) with error control (as scipy's RK45) and its quartic dense output on tout.
   Status: 0 done; 1 singular matrix, 2 not finite, 3 step size too small, 4 diverged (state at fail). */
int lg_dopri5(rhs_fn f, int dim, double t0, double t1, const double *y0, long nout, const double *tout, double rtol, double atol,
              double max_step, double first_step, double *Y, long *counts, double *fail) {
    static const double C[7] = {0.0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1.0, 1.0};
    static const double A[7][6] = {
        {0}, {1.0 / 5}, {3.0 / 40, 9.0 / 40}, {44.0 / 45, -56.0 / 15, 32.0 / 9},
        {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729},
        {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656},
        {35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}};
    static const double E[7] = {-71.0 / 57600, 0.0, 71.0 / 16695, -71.0 / 1920, 17253.0 / 339200, -22.0 / 525, 1.0 / 40};
    static const double P[7][4] = {
        {1.0, -8048581381.0 / 2820520608, 8663915743.0 / 2820520608, -12715105075.0 / 11282082432},
        {0.0, 0.0, 0.0, 0.0},
        {0.0, 131558114200.0 / 32700410799, -68118460800.0 / 10900136933, 87487479700.0 / 32700410799},
        {0.0, -1754552775.0 / 470086768, 14199869525.0 / 1410260304, -10690763975.0 / 1880347072},
        {0.0, 127303824393.0 / 49829197408, -318862633887.0 / 49829197408, 701980252875.0 / 199316789632},
        {0.0, -282668133.0 / 205662961, 2019193451.0 / 616988883, -1453857185.0 / 822651844},
        {0.0, 40617522.0 / 29380423, -110615467.0 / 29380423, 69997945.0 / 29380423}};
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0;
    double y[dim], ynew[dim], ys[dim], K[7][dim], err[dim], scale[dim], f1[dim];
    long nfev = 0, nstep = 0, nrej = 0, o = 0;
    int rc;
    double t = t0, limit = 1.0;
    memcpy(y, y0, sizeof y);
    for (int i = 0; i < dim; i++) if (fabs(y[i]) > limit) limit = fabs(y[i]);
    limit *= 1e30;
    rc = f(t, y, K[0]); nfev++;
    if (rc) { fail_at(dim, fail, t, y); counts[0] = nfev; return rc; }
    while (o < nout && tout[o] <= t0) { memcpy(Y + o * dim, y, sizeof y); o++; }
    double h = first_step;
    if (!(h > 0.0)) {  /* scipy's select_initial_step, error order 4 */
        for (int i = 0; i < dim; i++) scale[i] = atol + fabs(y[i]) * rtol;
        double d0 = rms_scaled(dim, y, scale), d1 = rms_scaled(dim, K[0], scale), h0;
        h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
        if (h0 > t1 - t0) h0 = t1 - t0;
        for (int i = 0; i < dim; i++) ys[i] = y[i] + h0 * K[0][i];
        rc = f(t + h0, ys, f1); nfev++;
        double d2 = 0.0;
        if (!rc) { for (int i = 0; i < dim; i++) err[i] = f1[i] - K[0][i]; d2 = rms_scaled(dim, err, scale) / h0; }
        double dm = d1 > d2 ? d1 : d2, h1;
        h1 = (dm <= 1e-15) ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / dm, 1.0 / 5.0);
        h = fmin(100 * h0, h1);
        if (h > t1 - t0) h = t1 - t0;
    }
    while (t < t1) {
        double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
        if (h > max_step) h = max_step;
        if (h < min_step) h = min_step;
        int rejected = 0;
        double tnew, hstep;
        for (;;) {
            if (h < min_step) { fail_at(dim, fail, t, y); counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return 3; }
            tnew = t + h;
            if (tnew > t1) tnew = t1;
            hstep = tnew - t;
            int bad = 0;
            for (int s = 1; s < 7 && !bad; s++) {
                double *target = (s == 6) ? ynew : ys;
                for (int i = 0; i < dim; i++) {
                    double acc = 0.0;
                    for (int j = 0; j < s; j++) acc += A[s][j] * K[j][i];
                    target[i] = y[i] + hstep * acc;
                }
                rc = f(s == 6 ? tnew : t + C[s] * hstep, target, K[s]); nfev++;
                if (rc == 1) { fail_at(dim, fail, t + C[s] * hstep, target); counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return 1; }
                if (rc) bad = 1;
            }
            double norm;
            if (bad) norm = INFINITY;
            else {
                for (int i = 0; i < dim; i++) {
                    double acc = 0.0;
                    for (int j = 0; j < 7; j++) acc += E[j] * K[j][i];
                    err[i] = hstep * acc;
                    scale[i] = atol + fmax(fabs(y[i]), fabs(ynew[i])) * rtol;
                }
                norm = rms_scaled(dim, err, scale);
                if (!(norm == norm)) norm = INFINITY;
            }
            if (norm < 1.0) {
                double factor = norm == 0.0 ? MAX_FACTOR : fmin(MAX_FACTOR, SAFETY * pow(norm, -0.2));
                if (rejected && factor > 1.0) factor = 1.0;
                h = hstep * factor;
                break;
            }
            h = hstep * fmax(MIN_FACTOR, norm == INFINITY ? MIN_FACTOR : SAFETY * pow(norm, -0.2));
            rejected = 1;
            nrej++;
        }
        /* dense output on (t, tnew] */
        while (o < nout && tout[o] <= tnew) {
            if (tout[o] == tnew) memcpy(Y + o * dim, ynew, sizeof ynew);
            else {
                double x = (tout[o] - t) / hstep, w[4] = {x, x * x, x * x * x, x * x * x * x};
                for (int i = 0; i < dim; i++) {
                    double acc = 0.0;
                    for (int j = 0; j < 7; j++) {
                        if (j == 1) continue;
                        acc += K[j][i] * (P[j][0] * w[0] + P[j][1] * w[1] + P[j][2] * w[2] + P[j][3] * w[3]);
                    }
                    Y[o * dim + i] = y[i] + hstep * acc;
                }
            }
            o++;
        }
        t = tnew;
        memcpy(y, ynew, sizeof y);
        memcpy(K[0], K[6], sizeof K[0]);
        nstep++;
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, t, y); counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return 4; }
    }
    counts[0] = nfev; counts[1] = nstep; counts[2] = nrej;
    return 0;
}

/* Fixed steps t_k = t0 + k h, k = 1..N: method 0 classical Runge-Kutta, 1 Stormer-Verlet (kick-drift-kick;
   separable models only: A constant, b independent of the velocities). Outputs tout: a step's state when
   within 1e-7 h of it, else cubic Hermite interpolation between the neighbouring steps.
   Status as lg_dopri5 (4: diverged). */
int lg_fixed(rhs_fn f, int nq, int dim, int method, double t0, double h, long N, const double *y0, long nout, const double *tout, double *Y,
             long *counts, double *fail) {
    double y[dim], ynew[dim], fv[dim], fnew[dim], k2[dim], k3[dim], k4[dim], ys[dim];
    long nfev = 0, o = 0;
    int rc;
    double limit = 1.0;
    memcpy(y, y0, sizeof y);
    for (int i = 0; i < dim; i++) if (fabs(y[i]) > limit) limit = fabs(y[i]);
    limit *= 1e30;
    rc = f(t0, y, fv); nfev++;
    if (rc) { fail_at(dim, fail, t0, y); counts[0] = nfev; return rc; }
    while (o < nout && (tout[o] - t0) / h < 1e-7) { memcpy(Y + o * dim, y, sizeof y); o++; }
    for (long k = 1; k <= N && o < nout; k++) {
        const double t = t0 + (k - 1) * h, tn = t0 + k * h;
        if (method == 0) {
            for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * fv[i];
            if ((rc = f(t + 0.5 * h, ys, k2))) { fail_at(dim, fail, t + 0.5 * h, ys); break; }
            for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * k2[i];
            if ((rc = f(t + 0.5 * h, ys, k3))) { fail_at(dim, fail, t + 0.5 * h, ys); break; }
            for (int i = 0; i < dim; i++) ys[i] = y[i] + h * k3[i];
            if ((rc = f(tn, ys, k4))) { fail_at(dim, fail, tn, ys); break; }
            for (int i = 0; i < dim; i++) ynew[i] = y[i] + h / 6.0 * (fv[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
            nfev += 3;
            if ((rc = f(tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); break; }
            nfev++;
        } else {  /* y = (q, v), f = (v, a): v += h/2 a; q += h v; a = a(q); v += h/2 a */
            for (int i = 0; i < nq; i++) { ynew[nq + i] = y[nq + i] + 0.5 * h * fv[nq + i]; ynew[i] = y[i] + h * ynew[nq + i]; }
            if ((rc = f(tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); break; }
            nfev++;
            for (int i = 0; i < nq; i++) { ynew[nq + i] += 0.5 * h * fnew[nq + i]; fnew[i] = ynew[nq + i]; }
        }
        while (o < nout && (tout[o] - t0) / h <= k + 1e-7) {
            double kf = (tout[o] - t0) / h;
            if (fabs(kf - k) < 1e-7) memcpy(Y + o * dim, ynew, sizeof ynew);
            else {
                double s = (tout[o] - t) / h, s2 = s * s, s3 = s2 * s;
                double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
                for (int i = 0; i < dim; i++)
                    Y[o * dim + i] = h00 * y[i] + h10 * h * fv[i] + h01 * ynew[i] + h11 * h * fnew[i];
            }
            o++;
        }
        memcpy(y, ynew, sizeof y);
        memcpy(fv, fnew, sizeof fv);
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, tn, y); rc = 4; break; }
    }
    counts[0] = nfev; counts[1] = o;
    return rc;
}
"""

# ---------------------------------------------------------------------------
# Build, cache, load
# ---------------------------------------------------------------------------


def _key(source: str, cc: str) -> str:
    text = "\n".join([CODEGEN_VERSION, _compiler_identity(cc), " ".join(FLAGS), sys.platform, source])
    return hashlib.sha256(text.encode()).hexdigest()[:32]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _load_cached(directory: Path, key: str) -> ctypes.CDLL | None:
    lib, manifest = directory / f"{key}.so", directory / f"{key}.json"
    try:
        recorded = json.loads(manifest.read_text())["sha256"]
        if _digest(lib) != recorded:
            raise ValueError("digest mismatch")
        return ctypes.CDLL(str(lib))
    except FileNotFoundError:
        return None
    except (OSError, ValueError, KeyError, TypeError) as exc:  # corrupt or half-deleted: rebuild
        _log.info("compiled model cache entry %s is unusable (%s); rebuilding", key, exc)
        return None


def _write_atomic(directory: Path, name: str, data: bytes) -> None:
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, directory / name)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _start(directory: Path, key: str, source: str, cc: str) -> tuple:
    """Start compiling ``source`` in the background (in a private temporary directory); see :func:`_finish`."""
    work = Path(tempfile.mkdtemp(dir=directory, prefix=".build-"))
    src, out = work / f"{key}.c", work / f"{key}.so"
    src.write_text(source)
    try:
        proc = subprocess.Popen([cc, *FLAGS, "-o", str(out), str(src), "-lm"], stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    except OSError as exc:
        shutil.rmtree(work, ignore_errors=True)
        raise _Unavailable(f"the C compiler {cc} could not be run ({exc})") from None
    return proc, work, key, source


def _finish(directory: Path, job: tuple, cc: str) -> ctypes.CDLL:
    """Wait for a compilation; store the library in the cache (atomically: temporary file, then rename); load it."""
    proc, work, key, source = job
    try:
        try:
            _, err = proc.communicate(timeout=600)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            raise _Unavailable(f"the C compiler {cc} took more than 600 s") from None
        if proc.returncode:
            first = "; ".join(err.strip().splitlines()[:3])
            raise _Unavailable(f"the C compiler {cc} failed (exit {proc.returncode}): {first}")
        data = (work / f"{key}.so").read_bytes()
        _write_atomic(directory, f"{key}.c", source.encode())
        _write_atomic(directory, f"{key}.so", data)
        manifest = {"sha256": hashlib.sha256(data).hexdigest(), "compiler": _compiler_identity(cc), "flags": list(FLAGS),
                    "codegen": CODEGEN_VERSION, "created": time.time()}
        _write_atomic(directory, f"{key}.json", json.dumps(manifest).encode())
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return ctypes.CDLL(str(directory / f"{key}.so"))


def _libraries(directory: Path, source: str, cc: str) -> tuple[ctypes.CDLL, ctypes.CDLL, str, bool]:
    """The model's library and the stepping loops' library, from the cache or compiled (both at once)."""
    key, loops_key = _key(source, cc), "loops-" + _key(_LOOPS, cc)
    found = {name: _load_cached(directory, k) for name, k in (("model", key), ("loops", loops_key))}
    missing = {name: (k, text) for name, k, text in (("model", key, source), ("loops", loops_key, _LOOPS))
               if found[name] is None}
    if missing:
        directory.mkdir(parents=True, exist_ok=True)
        jobs, failure = {}, None
        for name, (k, text) in missing.items():
            try:
                jobs[name] = _start(directory, k, text, cc)
            except _Unavailable as exc:
                failure = failure or exc
        for name, job in jobs.items():  # finish every job started, even after a failure
            try:
                found[name] = _finish(directory, job, cc)
            except _Unavailable as exc:
                failure = failure or exc
        if failure is not None:
            raise failure
    return found["model"], found["loops"], key, "model" not in missing


def compile_model(numeric) -> tuple[CompiledModel | None, str | None]:
    """``(CompiledModel, None)`` for ``numeric``, from the cache or freshly built; ``(None, reason)`` when it cannot be.

    Never raises for a missing compiler, a failed compilation, an
    unwritable cache or callable signals: the reason comes back (and is
    logged) so that the caller can use the NumPy path.
    """
    start = time.perf_counter()
    try:
        source = generate_source(numeric)
        codegen_s = time.perf_counter() - start
        cc = compiler()
        if cc is None:
            wanted = _settings["compiler"] or os.environ.get("LAGRANGIAN_CC")
            raise _Unavailable(f"no C compiler found ({f'{wanted!r} is not a program on the PATH' if wanted else 'none of cc, gcc, clang on the PATH'}); "
                               f"install one or set LAGRANGIAN_CC")
        directory = cache_dir()
        try:
            lib, loops, key, from_cache = _libraries(directory, source, cc)
        except OSError as exc:
            raise _Unavailable(f"the cache directory {directory} is not usable ({exc}); set LAGRANGIAN_CACHE_DIR") from None
    except _Unavailable as exc:
        note = f"compiled code not used ({exc}): the NumPy path evaluates the model instead"
        _log.info(note)
        return None, note
    compiled = CompiledModel(numeric, lib, loops, key, directory / f"{key}.so", from_cache=from_cache,
                             codegen_seconds=codegen_s, build_seconds=time.perf_counter() - start)
    return compiled, None


class CompiledModel:
    """The compiled functions of one :class:`~lagrangian.simulation.NumericModel` (see :func:`compile_model`).

    ``from_cache`` says whether the library came from the disk cache (else
    it was just built); ``path`` is the library; ``key`` its cache key;
    ``codegen_seconds`` and ``build_seconds`` the time spent generating the
    source and, in all, getting the library.
    """

    def __init__(self, numeric, lib: ctypes.CDLL, loops: ctypes.CDLL, key: str, path: Path, *, from_cache: bool,
                 codegen_seconds: float, build_seconds: float):
        self.numeric, self.lib, self.loops, self.key, self.path = numeric, lib, loops, key, path
        self.from_cache, self.codegen_seconds, self.build_seconds = from_cache, codegen_seconds, build_seconds
        self.n, self.nI, self.dim = numeric.n, numeric.nI, numeric.n + numeric.nI
        dims = (ctypes.c_int * 4)()
        lib.lg_dims(dims)
        self.m = dims[2]
        if (dims[0], dims[1]) != (self.n, self.nI):  # pragma: no cover - a stale or foreign library
            raise NumericalError(f"the compiled library {path} does not belong to this model; delete it and retry.")
        dbl, ptr, lng = ctypes.c_double, ctypes.c_void_p, ctypes.c_long
        lib.lg_rhs.argtypes, lib.lg_rhs.restype = [dbl, ptr, ptr], ctypes.c_int
        lib.lg_matrix.argtypes, lib.lg_matrix.restype = [dbl, ptr, ptr, ptr, ptr], None
        lib.lg_energies.argtypes, lib.lg_energies.restype = [lng, ptr, ptr, ptr, ptr], None
        cint = ctypes.c_int
        loops.lg_velocities.argtypes, loops.lg_velocities.restype = [ptr, cint, cint, lng, ptr, ptr, ptr], lng
        loops.lg_dopri5.argtypes = [ptr, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl, dbl, ptr, ptr, ptr]
        loops.lg_dopri5.restype = cint
        loops.lg_fixed.argtypes = [ptr, cint, cint, cint, dbl, dbl, lng, ptr, lng, ptr, ptr, ptr, ptr]
        loops.lg_fixed.restype = cint
        self._rhs_c = lib.lg_rhs
        self._rhs_ptr = ctypes.cast(lib.lg_rhs, ctypes.c_void_p).value  # what the loops call
        self._y = np.zeros(max(self.dim, 1))
        self._dy = np.zeros(max(self.dim, 1))
        self._yp, self._dyp = self._y.ctypes.data, self._dy.ctypes.data

    # -- one state ----------------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt`` at ``(t, y)``, ``y = (q, q̇_inertial)``: the same as ``NumericModel.rhs``, in C."""
        self._y[: self.dim] = y
        rc = self._rhs_c(t, self._yp, self._dyp)
        if rc:
            self._raise(rc, t, self._y[: self.dim].copy())
        return self._dy[: self.dim].copy()

    def matrix(self, t: float, q: np.ndarray, vI: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``A`` and ``b`` of the solve ``A u = b`` at ``(t, q, q̇_inertial)``."""
        A, b = np.zeros((self.m, self.m)), np.zeros(self.m)
        q = np.ascontiguousarray(q, dtype=float)
        vI = np.ascontiguousarray(vI, dtype=float)
        self.lib.lg_matrix(t, q.ctypes.data, vI.ctypes.data if vI.size else None, A.ctypes.data, b.ctypes.data)
        return A, b

    def _raise(self, rc: int, t: float, y: np.ndarray):
        if rc == 1:
            A, _ = self.matrix(t, y[: self.n], y[self.n :])
            raise SingularMassMatrixError(self.numeric._singular_message(t, A))
        raise NumericalError(
            f"the equations are not finite at t={t:g} (state {np.array2string(y, precision=4)}): a singular "
            f"configuration of some component, or a diverging solution. Start elsewhere or reduce the step."
        )

    # -- many states ------------------------------------------------------------
    def velocities_many(self, times: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """All generalized velocities (``n × N``) at the states ``Y`` (columns)."""
        times = np.ascontiguousarray(times, dtype=float)
        rows = np.ascontiguousarray(np.asarray(Y, dtype=float).T)
        out = np.empty((times.size, self.n))
        k = self.loops.lg_velocities(self._rhs_ptr, self.n, self.dim, times.size, times.ctypes.data, rows.ctypes.data,
                                     out.ctypes.data)
        if k >= 0:
            dy = np.empty(self.dim)
            self._raise(self.lib.lg_rhs(times[k], rows[k].ctypes.data, dy.ctypes.data) or 2, times[k], rows[k])
        return out.T.copy()

    def _energies(self, times, q, v) -> np.ndarray:
        times = np.ascontiguousarray(np.broadcast_to(np.asarray(times, dtype=float), (np.shape(q)[1],)))
        qr = np.ascontiguousarray(np.asarray(q, dtype=float).T)
        vr = np.ascontiguousarray(np.asarray(v, dtype=float).T)
        out = np.empty((times.size, 4))
        self.lib.lg_energies(times.size, times.ctypes.data, qr.ctypes.data, vr.ctypes.data, out.ctypes.data)
        return out

    def energies(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``T``, ``V``, ``D`` at many states (``q``, ``v``: ``n × N``)."""
        out = self._energies(times, q, v)
        return out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy()

    def jacobi(self, times: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The Jacobi integral ``h = p·q̇ − L`` at many states (``q``, ``v``: ``n × N``)."""
        return self._energies(times, q, v)[:, 3].copy()

    # -- stepping loops -----------------------------------------------------------
    def _run(self, status: int, fail: np.ndarray, what: str) -> str:
        t, y = float(fail[0]), fail[1:]
        if status == 1:
            self._raise(1, t, y)
        return {
            2: f"the equations became non-finite at t={t:g}",
            3: f"{what}: the step size fell below the resolution of t at t={t:g} (the model may be stiff or singular there)",
            4: f"the state diverged (beyond 1e30 times its initial size, or non-finite) by t={t:g}",
        }[status]

    def dopri5(self, t_span, y0, t_eval, *, rtol: float, atol: float, max_step: float, first_step: float | None):
        """Dormand–Prince 5(4) in C from ``y0``; ``(Y (dim × len), nfev, status, message)``; output stops at a failure."""
        t_eval = np.ascontiguousarray(t_eval, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        Y = np.full((t_eval.size, self.dim), np.nan)
        counts = np.zeros(3, dtype=np.int64)  # long is 64-bit on the platforms we build on
        fail = np.zeros(self.dim + 1)
        status = self.loops.lg_dopri5(self._rhs_ptr, self.dim, float(t_span[0]), float(t_span[1]), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
                                    float(rtol), float(atol), float(max_step) if math.isfinite(max_step) else 1e300,
                                    float(first_step or 0.0), Y.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        message = self._run(status, fail, "dopri5_c") if status else ""
        return Y.T, int(counts[0]), int(counts[1]), message

    def fixed(self, method: str, t0: float, h: float, N: int, y0, t_eval):
        """``N`` steps of ``rk4`` or ``verlet`` in C; ``(Y (dim × len), nfev, message)``."""
        t_eval = np.ascontiguousarray(t_eval, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        Y = np.full((t_eval.size, self.dim), np.nan)
        counts = np.zeros(2, dtype=np.int64)
        fail = np.zeros(self.dim + 1)
        code = {"rk4": 0, "verlet": 1}[method]
        status = self.loops.lg_fixed(self._rhs_ptr, self.n, self.dim, code, float(t0), float(h), int(N), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
                                   Y.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        message = self._run(status, fail, method) if status else ""
        return Y.T, int(counts[0]), message


# ---------------------------------------------------------------------------
# Integrators whose stepping loop is C
# ---------------------------------------------------------------------------


def _compiled_or_note(problem, name: str, sibling) -> tuple[CompiledModel | None, str | None]:
    compiled = problem.numeric.compile()
    if compiled is None:
        note = (f"{name}: {problem.numeric.compile_note}; ran its Python sibling "
                f"{getattr(sibling, 'name', sibling)!r} instead")
        _log.info(note)
        return None, note
    return compiled, None


class CompiledDormandPrince(Integrator):
    """Dormand–Prince 5(4) (scipy's ``RK45``) with its whole stepping loop in C.

    The same pair, error norm, step-size control and initial step as
    :class:`scipy.integrate.RK45`, and its quartic dense output at the
    output times, so it agrees with ``RK45`` to within the tolerance; no
    Python runs per step.  Needs a C compiler: without one (or for a model
    with Python-callable signals) it runs ``fallback`` (``RK45``) and says
    so in ``Result.notes``.
    """

    kind = "adaptive"
    order = 5
    needs_compiled = True
    symplectic = implicit = stiff = False
    first_order = True
    options = {"first_step": "initial step size (default: chosen as scipy does)"}

    def __init__(self, fallback: Integrator, name: str = "dopri5_c"):
        self.name, self.fallback = name, fallback
        self.description = "Dormand–Prince 5(4) (as RK45) with the stepping loop compiled to C; explicit, adaptive"

    def solve(self, problem, t_span, y0, t_eval, *, rtol=1e-9, atol=1e-12, max_step=np.inf, first_step=None):
        """Integrate in C (see the class documentation)."""
        compiled, note = _compiled_or_note(problem, self.name, self.fallback)
        if compiled is None:
            sol = self.fallback.solve(problem, t_span, y0, t_eval, rtol=rtol, atol=atol, max_step=max_step, first_step=first_step)
            sol.notes.insert(0, note)
            return sol
        if not (rtol > 0 and atol >= 0):
            raise ModelError(f"{self.name}: rtol must be positive and atol non-negative, got rtol={rtol!r}, atol={atol!r}.")
        if not (max_step > 0):
            raise ModelError(f"{self.name}: max_step must be positive, got {max_step!r}.")
        if first_step is not None and not (0 < first_step <= t_span[1] - t_span[0]):
            raise ModelError(f"{self.name}: first_step must be positive and within the time span, got {first_step!r}.")
        Y, nfev, nstep, message = compiled.dopri5(t_span, y0, t_eval, rtol=rtol, atol=atol, max_step=max_step,
                                                  first_step=first_step)
        problem.nfev += nfev
        problem.report(float(t_span[1]))
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        notes = [f"{self.name}: {nstep} steps in compiled code ({compiled.path.name}"
                 f"{', from the cache' if compiled.from_cache else ', built now'})"]
        return Solution(np.asarray(t_eval)[:count], Y[:, :count], nfev, -1 if message else 0, message, notes)


class CompiledFixedStep(FixedStepIntegrator):
    """A fixed-step method whose stepping loop is C: ``rk4`` (classical Runge–Kutta) or ``verlet`` (Störmer–Verlet).

    The same steps as the Python sibling ``fallback`` (uniform ``h`` from
    ``step``, outputs on the steps or by cubic Hermite interpolation between
    them), the same refusals (``fallback.check``: Störmer–Verlet refuses
    models that are not separable).  Without a C compiler it runs
    ``fallback`` and says so in ``Result.notes``.  Linear models are not
    advanced by powers of the one-step map: every step is taken.
    """

    def __init__(self, method: str, fallback: FixedStepIntegrator):
        if method not in ("rk4", "verlet"):
            raise ModelError(f"CompiledFixedStep: method must be 'rk4' or 'verlet', got {method!r}.")
        self.method, self.fallback, self.name = method, fallback, f"{method}_c"
        self.needs_compiled = True
        for attr in ("order", "symplectic", "implicit", "stiff", "first_order"):
            setattr(self, attr, getattr(fallback, attr))
        self.options = {}
        self.description = f"{fallback.description}; stepping loop compiled to C"

    def check(self, problem):
        """The sibling's refusals, under this method's name."""
        try:
            self.fallback.check(problem)
        except ModelError as exc:
            raise ModelError(str(exc).replace(f"{self.fallback.name} (", f"{self.name} (", 1)) from None

    def solve(self, problem, t_span, y0, t_eval, *, step=None, fast_linear=True, **options):
        """Integrate in C with uniform steps of at most ``step`` (``fast_linear`` is accepted and ignored)."""
        compiled, note = _compiled_or_note(problem, self.name, self.fallback)
        if compiled is None:
            sol = self.fallback.solve(problem, t_span, y0, t_eval, step=step, fast_linear=fast_linear, **options)
            sol.notes.insert(0, note)
            return sol
        t0, t1 = map(float, t_span)
        t_eval = np.asarray(t_eval, dtype=float)
        h, N, notes = _grid(self.name, problem, t0, t1, t_eval, step, np.asarray(y0, dtype=float))
        Y, nfev, message = compiled.fixed(self.method, t0, h, N, y0, t_eval)
        problem.nfev += nfev
        problem.report(t1)
        done = np.all(np.isfinite(Y), axis=0)
        count = int(np.argmin(done)) if not done.all() else t_eval.size
        k = (t_eval - t0) / h
        between = int(np.sum(np.abs(k - np.rint(k)) >= 1e-7))
        if between:
            notes.append(f"{between} output time(s) fall between steps: cubic Hermite interpolation (error O(h⁴))")
        notes.append(f"{self.name}: {N} steps in compiled code ({compiled.path.name})")
        return Solution(t_eval[:count], Y[:, :count], nfev, -1 if message else 0, message, notes, h)
