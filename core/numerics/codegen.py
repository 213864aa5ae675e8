"""Compiled models: the right-hand side in C, without compiling anything per model unless asked.

A :class:`~lagrangian.simulation.NumericModel` is recorded as two tapes
(:mod:`lagrangian.tape`, :func:`programs`): straight-line programs for the
entries of ``A(t, q, q̇)`` and ``b(t, q, q̇)`` of the solve ``A u = b`` (see
:mod:`lagrangian.equations`), and for ``T, V, D, L`` and the momenta (the
energies and the Jacobi integral), every common subexpression computed
once.  Recording takes about a millisecond.  The tapes are then run one of
two ways (:func:`compile_model`'s ``kind``):

- **the tape interpreter** (``"tape"``), a loop over the instructions in the
  *runtime library* — C that is the same for every model, compiled once per
  compiler and kept in the cache: a model runs the moment its equations are
  derived;
- **native code** (``"native"``), the tapes printed as straight-line C and
  compiled into the model's own library: about twice as fast per evaluation,
  after a C compilation of 0.1–0.5 s (once: the library is cached).

``"auto"`` takes the native library when it is already in the cache, else
the tape.  Either way the solve itself is done in C by a small dense LU
factorization with partial pivoting (``M⁻¹`` is never formed symbolically),
so that one call gives the derivative of the state ``(q, q̇_inertial)``; and
the runtime library holds stepping loops in C — an adaptive Dormand–Prince
5(4) pair with dense output, classical Runge–Kutta and Störmer–Verlet —
which the integrators ``dopri5_c``, ``rk4_c`` and ``verlet_c``
(:mod:`lagrangian.compiled_loops`, registered by the built-in integrators
plugin) run without returning to Python per step.

The system C compiler (``cc``, ``gcc`` or ``clang``; :func:`set_compiler`
or the environment variable ``LAGRANGIAN_CC`` choose another) builds shared
libraries (``-O2 -ffp-contract=off -shared -fPIC``: no fused multiply–adds, so that native code and the tape give the same numbers) loaded with :mod:`ctypes`: no dependency
beyond a C compiler.  Libraries are cached on disk, keyed by a hash of their
source (for a native library: the model's expressions with its numeric
parameter values), the compiler and its flags.  :func:`runtime` builds the
runtime library ahead of time (as an installation step would).

Measured on the planar n-link pendulum (``benchmarks/rhs.py``), n = 3–10:
one evaluation in C takes 0.2–1.2 µs on the tape and 0.1–0.5 µs native (a
hand-written C function of the same system with the same LU takes about as
long as native); called from Python, 1.2–2.2 µs and 1.1–1.5 µs.  The cache
lives in ``$LAGRANGIAN_CACHE_DIR``, else ``$XDG_CACHE_HOME/lagrangian``,
else ``~/.cache/lagrangian`` (:func:`cache_dir`, :func:`set_cache_dir`); it
is safe to delete at any time — a missing or corrupt entry is rebuilt, and
entries are written to a temporary file and renamed, so that two processes
never see half a library.

When no compiler is found, compilation fails, or the model uses a time
signal given as a Python callable (which C cannot call) or a function the
tape does not know, nothing crashes: :func:`compile_model` returns ``None``
with the reason, which ``Model.simulate`` logs and puts in
``Result.notes`` before using the NumPy path.  A singular matrix met in C
raises :class:`~lagrangian.SingularMassMatrixError`, a non-finite
derivative :class:`~lagrangian.NumericalError`.

>>> import tempfile, lagrangian as lg
>>> set_cache_dir(tempfile.mkdtemp())          # a private cache for this example
>>> m = lg.Model("oscillator")
>>> _ = m.add("mass", "m", "p", m=2)
>>> _ = m.add("spring", "k", ("ground", "p"), k=8)
>>> compiled, note = compile_model(m.numeric(), "tape")  # (None, why) without a C compiler
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
import stat
import subprocess
import sys
import threading
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import sympy as sp

from ..base.component import t as time_symbol
from ..errors import ModelError, NumericalError, SingularMassMatrixError
from .tape import OPS, Program, TapeError, record

__all__ = [
    "CompiledModel",
    "compile_model",
    "generate_source",
    "programs",
    "run_program",
    "runtime",
    "cache_dir",
    "set_cache_dir",
    "compiler",
    "set_compiler",
    "FLAGS",
]

_log = logging.getLogger("lagrangian")

#: Flags of every compilation (part of the cache key).
FLAGS = ("-O2", "-ffp-contract=off", "-shared", "-fPIC")
#: Bumped whenever the generated C changes shape, so that old cache entries are not reused.
CODEGEN_VERSION = "2"
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


def _trusted(directory: Path) -> str | None:
    """Why ``directory`` may not hold libraries this process loads (``None``: it may).

    Created ``0700`` when missing.  Refused, as ccache and pip refuse theirs,
    when it is not a directory, is owned by another user, or is writable by
    the group or by everyone: whoever can write there could put a library
    that runs code in this process.
    """
    try:
        directory.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = directory.stat()
    except OSError as exc:
        return f"the cache directory {directory} is not usable ({exc})"
    if not stat.S_ISDIR(info.st_mode):
        return f"the cache path {directory} is not a directory"
    if hasattr(os, "getuid") and info.st_uid != os.getuid():
        return f"the cache directory {directory} belongs to another user (uid {info.st_uid})"
    if info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"the cache directory {directory} is writable by others (mode {stat.S_IMODE(info.st_mode):o})"
    return None


def _cache() -> tuple[Path, str | None]:
    """The directory to build in and load from: :func:`cache_dir` when it is trusted, else a private directory
    of this process (made once, ``0700``), with a note saying why."""
    directory = cache_dir()
    why = _trusted(directory)
    if why is None:
        return directory, None
    if _settings.get("private") is None:
        _settings["private"] = tempfile.mkdtemp(prefix="lagrangian-cache-")
    note = f"{why}; compiled code is built in a private directory of this process instead (set LAGRANGIAN_CACHE_DIR " \
           f"to a directory of your own, mode 700)"
    _log.warning(note)
    return Path(_settings["private"]), note


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


def _arrays(numeric) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    """The entries of ``A`` and ``b``, and ``T, V, D, L`` and the momenta ``p = ∂L/∂q̇`` (for the Jacobi integral
    ``h = p·q̇ − L``), generic: every parameter with a value (given as a number or by ``params=``) a symbol."""
    return _arrays_of(numeric.eq)


def _arrays_of(eq) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    g = eq.generic()
    energies = [g["T"], g["V"], g["D"], g["L"], *g["p"]]
    return list(g["A"]), list(g["b"]), energies


def c_comment(text: str) -> str:
    """``text`` as one C comment line: the only way user text (coordinate names) enters generated C.

    Characters other than letters, digits, space and ``_ , . ; : ( ) - + =``
    become ``?``, so nothing in the text can end the comment (``*/``),
    splice lines (a backslash before a newline), start a preprocessor line
    or a trigraph.

    >>> c_comment("coordinates x_p, y*/ system(1); /*" + chr(92))
    '/* coordinates x_p, y?? system(1); ??? */'
    """
    safe = "".join(ch if (ch.isascii() and ch.isalnum()) or ch in " _,.;:()-+=" else "?" for ch in text)
    return f"/* {safe} */"


def programs(numeric) -> tuple[Program, Program]:
    """The two tapes (:mod:`lagrangian.tape`) of ``numeric``: ``A`` and ``b`` from ``(t, q, q̇_inertial)``, and
    ``T, V, D, L, p`` from ``(t, q, q̇)``, with ``numeric``'s parameter values in their constant registers.

    The tapes are recorded once per model (kept on its equations), with the
    parameters as registers whose values are put in for each set of values
    (:meth:`lagrangian.tape.Program.with_values`): new values record
    nothing again, and the tape interpreter runs them at once.

    Raises an internal error (turned into a note by :func:`compile_model`)
    when the model cannot be compiled: time signals given as Python
    callables, or functions the tape does not know.
    """
    found = getattr(numeric, "_tapes", None)
    if found is not None:
        return found
    generic = _generic_programs(numeric.eq, tuple(sorted(numeric.values, key=sp.default_sort_key)))
    try:
        numeric._tapes = tuple(p.with_values(numeric.values) for p in generic)
    except TapeError as exc:  # pragma: no cover - every parameter has a value by Model._values
        raise _Unavailable(str(exc)) from None
    return numeric._tapes


def _generic_programs(eq, parameters: tuple) -> tuple[Program, Program]:
    """The tapes of ``eq`` with ``parameters`` as run-time constants, recorded once per set of parameter symbols."""
    cache = eq.__dict__.setdefault("_generic_tapes", {})
    if parameters in cache:
        return cache[parameters]
    a_entries, b_entries, energies = _arrays_of(eq)
    scan = eq.scan()
    callables = scan["callables"]
    if callables or scan["derivatives"]:
        raise _Unavailable(
            f"the model uses time signal(s) given as Python callables ({', '.join(callables) or 'derivatives'}), "
            f"which compiled code cannot call; give them as SymPy expressions of t to compile"
        )
    q, v = list(eq.sym.q), list(eq.sym.v)
    try:
        matrix = record([*a_entries, *b_entries], [time_symbol, *q, *(v[i] for i in eq.inertial)], parameters)
        energy = record(energies, [time_symbol, *q, *v], parameters)
    except TapeError as exc:
        raise _Unavailable(str(exc)) from None
    cache[parameters] = (matrix, energy)
    return cache[parameters]


def generate_source(numeric) -> str:
    """The C source of ``numeric``'s native library (a :class:`~lagrangian.simulation.NumericModel`):
    its tapes (:func:`programs`) printed as straight-line C — ``lg_matrix`` (the entries of ``A`` and ``b``),
    ``lg_rhs`` (that and the LU solve: the state derivative) and ``lg_energies`` (``T``, ``V``, ``D``,
    Jacobi integral); the stepping loops are in the runtime library, shared by every model.
    """
    eq = numeric.eq
    matrix, energy = programs(numeric)
    n, nI = numeric.n, numeric.nI
    first = list(eq.first_order)
    m = int(math.isqrt(len(numeric.eq.generic()["A"])))
    inputs_m = {0: "t", **{1 + i: f"q[{i}]" for i in range(n)}, **{1 + n + j: f"vI[{j}]" for j in range(nI)}}
    inputs_e = {0: "t", **{1 + i: f"q[{i}]" for i in range(n)}, **{1 + n + i: f"v[{i}]" for i in range(n)}}
    body_m = matrix.c_lines(inputs_m, [f"A[{k}]" for k in range(m * m)] + [f"b[{k}]" for k in range(m)], "    ")
    body_e = energy.c_lines(inputs_e, [f"o[{k}]" for k in range(4 + n)], "    ")

    def table(values):
        return "{" + ", ".join(map(str, values or [0])) + "}"

    return "\n".join([
        c_comment(f"Generated by lagrangian.codegen {CODEGEN_VERSION}; coordinates {', '.join(numeric.eq.names)}; "
                  f"do not edit."),
        _HEADER,
        f"#define NQ {n}",
        f"#define NI {nI}",
        f"#define NF {len(first)}",
        f"#define NM {m}",
        f"static const int INERTIAL[] = {table(eq.inertial)};",
        f"static const int FIRST[] = {table(first)};",
        _SOLVE,
        "int lg_dims(int *out) { out[0] = NQ; out[1] = NI; out[2] = NM; out[3] = NF; return 0; }",
        "",
        "/* The entries of A (row-major, NM x NM) and b of the solve A u = b, u = (accelerations, first-order rates, multipliers). */",
        "int lg_matrix(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {",
        *body_m,
        "    return 0;",
        "}",
        "",
        "/* T, V, D, L and the momenta p at (t, q, v), v: the rates of all coordinates. */",
        "static void energy_terms(double t, const double *q, const double *v, double *o) {",
        *body_e,
        "}",
        _NATIVE,
    ]) + "\n"


_HEADER = """#include <math.h>
#include <float.h>
#include <stdlib.h>
#include <string.h>
/* Scratch arrays: on the stack up to LG_SCRATCH doubles, on the heap beyond (a model of 10^4 coordinates needs
   more than any thread's stack); NULL when the heap has none. RELEASE frees what SCRATCH took from the heap. */
#define LG_SCRATCH 2048
#define SCRATCH(name, count) double name##_stack[LG_SCRATCH]; \
    double *name = (count) <= LG_SCRATCH ? name##_stack : malloc((size_t)(count) * sizeof(double))
#define RELEASE(name) do { if (name != name##_stack) free(name); } while (0)
"""

# The solve and the state derivative: one text, in the runtime library (sizes as arguments) and in every native
# library (sizes as constants, which the C compiler folds into the loops).
_SOLVE = r"""
/* LU with partial pivoting, in place; b becomes the solution. 0: solved, 1: singular, 2: not finite. */
static int lu_solve(int nm, double *A, double *b) {
    double amax = 0.0;
    for (int i = 0; i < nm * nm; i++) {
        double a = fabs(A[i]);
        if (!(a <= DBL_MAX)) return 2;
        if (a > amax) amax = a;
    }
    const double tiny = nm * DBL_EPSILON * amax;
    if (nm && !(amax > 0.0)) return 1;
    for (int k = 0; k < nm; k++) {
        int p = k;
        double best = fabs(A[k * nm + k]);
        for (int i = k + 1; i < nm; i++) {
            double a = fabs(A[i * nm + k]);
            if (a > best) { best = a; p = i; }
        }
        if (!(best > tiny)) return best == best ? 1 : 2;
        if (p != k) {
            for (int j = k; j < nm; j++) { double s = A[k * nm + j]; A[k * nm + j] = A[p * nm + j]; A[p * nm + j] = s; }
            double s = b[k]; b[k] = b[p]; b[p] = s;
        }
        const double inv = 1.0 / A[k * nm + k];
        for (int i = k + 1; i < nm; i++) {
            const double f = A[i * nm + k] * inv;
            if (f != 0.0) {
                for (int j = k + 1; j < nm; j++) A[i * nm + j] -= f * A[k * nm + j];
                b[i] -= f * b[k];
            }
        }
    }
    for (int k = nm - 1; k >= 0; k--) {
        double s = b[k];
        for (int j = k + 1; j < nm; j++) s -= A[k * nm + j] * b[j];
        b[k] = s / A[k * nm + k];
    }
    return 0;
}

/* dy/dt from the solution u = b of A u = b at y = (q, q'_inertial). 0: fine, 2: not finite. */
static int state_rate(int nq, int ni, int nf, const int *inertial, const int *first, const double *y, const double *b,
                      double *dy) {
    for (int j = 0; j < ni; j++) { dy[inertial[j]] = y[nq + j]; dy[nq + j] = b[j]; }
    for (int j = 0; j < nf; j++) dy[first[j]] = b[ni + j];
    for (int i = 0; i < nq + ni; i++) if (!isfinite(dy[i])) return 2;
    return 0;
}

/* T, V, D and the Jacobi integral h = p.v - L into out[0..3], from o = (T, V, D, L, p). */
static void energy_out(int nq, const double *v, const double *o, double *out) {
    double h = -o[3];
    for (int i = 0; i < nq; i++) h += v[i] * o[4 + i];
    out[0] = o[0]; out[1] = o[1]; out[2] = o[2]; out[3] = h;
}
"""

# The native library's entry points (its sizes are constants; ctx is unused: the functions are the model).
_NATIVE = r"""
int lg_rhs(const void *ctx, double t, const double *y, double *dy) {
    SCRATCH(A, NM * NM + NM + 1);
    if (!A) return 2;
    double *b = A + NM * NM;
    lg_matrix(ctx, t, y, y + NQ, A, b);
    int rc = lu_solve(NM, A, b);
    if (!rc) rc = state_rate(NQ, NI, NF, INERTIAL, FIRST, y, b, dy);
    RELEASE(A);
    return rc;
}

void lg_energies(const void *ctx, long N, const double *t, const double *q, const double *v, double *out) {
    SCRATCH(o, 4 + NQ);
    for (long k = 0; k < N; k++) {
        if (!o) { for (int i = 0; i < 4; i++) out[4 * k + i] = NAN; continue; }
        energy_terms(t[k], q + k * NQ, v + k * NQ, o);
        energy_out(NQ, v + k * NQ, o, out + 4 * k);
    }
    RELEASE(o);
}
"""


def _interpreter() -> str:
    """The C interpreter of tapes: one ``case`` per operation of :data:`lagrangian.tape.OPS`."""
    cases = "\n".join(f"        case {k}: r[c[1]] = {template}; break;" for k, (_, template) in enumerate(OPS.values()))
    return r"""
/* A tape (lagrangian.tape.Program): registers = inputs, constants, temporaries; rows (op, dst, x, y, z). */
typedef struct { int nin, nconst, ninstr, nout; const double *consts; const int *code; const int *out; } lg_prog;
/* A model as two tapes: A and b from (t, q, q'_inertial); T, V, D, L, p from (t, q, q'). */
typedef struct { int nq, ni, nf, nm; const int *inertial, *first; lg_prog matrix, energy; } lg_tape;

static void run(const lg_prog *p, double *r) {
    memcpy(r + p->nin, p->consts, p->nconst * sizeof(double));
    for (const int *c = p->code, *end = p->code + 5 * p->ninstr; c < end; c += 5) {
        const double x = r[c[2]], y = r[c[3]], z = r[c[4]];
        (void)y; (void)z;
        switch (c[0]) {
""" + cases + r"""
        }
    }
}

#define ON_STACK 4096
/* Run p on the inputs (t, a[na], b[nb]); its outputs into out. 0: done, 2: out of memory. */
static int run_on(const lg_prog *p, double t, const double *a, int na, const double *b, int nb, double *out) {
    double stack[ON_STACK];
    const int nreg = p->nin + p->nconst + p->ninstr + 1;
    double *r = nreg <= ON_STACK ? stack : malloc(nreg * sizeof(double));
    if (!r) return 2;
    r[0] = t;
    memcpy(r + 1, a, na * sizeof(double));
    if (nb) memcpy(r + 1 + na, b, nb * sizeof(double));
    run(p, r);
    for (int k = 0; k < p->nout; k++) out[k] = r[p->out[k]];
    if (r != stack) free(r);
    return 0;
}

/* Run p on inputs in[nin]: its outputs into out (N sets of inputs, rows). 0: done, 2: out of memory. */
int lg_prog_eval(const lg_prog *p, long N, const double *in, double *out) {
    for (long k = 0; k < N; k++) {
        const double *row = in + k * p->nin;
        if (run_on(p, p->nin ? row[0] : 0.0, row + 1, p->nin ? p->nin - 1 : 0, row, 0, out + k * p->nout)) return 2;
    }
    return 0;
}

int lg_tape_matrix(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {
    const lg_tape *m = ctx;
    SCRATCH(o, (long)m->nm * m->nm + m->nm + 1);
    if (!o) return 2;
    int rc = run_on(&m->matrix, t, q, m->nq, vI, m->ni, o);
    memcpy(A, o, (size_t)m->nm * m->nm * sizeof(double));
    memcpy(b, o + (long)m->nm * m->nm, m->nm * sizeof(double));
    RELEASE(o);
    return rc;
}

int lg_tape_rhs(const void *ctx, double t, const double *y, double *dy) {
    const lg_tape *m = ctx;
    const long nm = m->nm;
    SCRATCH(o, nm * nm + nm + 1);
    if (!o) return 2;
    int rc = run_on(&m->matrix, t, y, m->nq, y + m->nq, m->ni, o);
    if (!rc) rc = lu_solve(nm, o, o + nm * nm);
    if (!rc) rc = state_rate(m->nq, m->ni, m->nf, m->inertial, m->first, y, o + nm * nm, dy);
    RELEASE(o);
    return rc;
}

void lg_tape_energies(const void *ctx, long N, const double *t, const double *q, const double *v, double *out) {
    const lg_tape *m = ctx;
    const int nq = m->nq;
    SCRATCH(o, 4 + nq);
    for (long k = 0; k < N; k++) {
        if (!o || run_on(&m->energy, t[k], q + k * nq, nq, v + k * nq, nq, o)) { for (int i = 0; i < 4; i++) out[4 * k + i] = NAN; continue; }
        energy_out(nq, v + k * nq, o, out + 4 * k);
    }
    RELEASE(o);
}
"""


# The stepping loops, the same for every model: they call the model's right-hand side through f(ctx, ...).
_LOOPS = r"""
typedef int (*rhs_fn)(const void *ctx, double t, const double *y, double *dy);

/* All rates v (length nq) at many states (rows of Y, N x dim). Returns -1 or the index of the first failure. */
long lg_velocities(rhs_fn f, const void *ctx, int nq, int dim, long N, const double *t, const double *Y, double *V) {
    SCRATCH(dy, dim);
    long failed = dy ? -1 : 0;
    for (long k = 0; k < N && failed < 0; k++) {
        if (f(ctx, t[k], Y + k * dim, dy)) failed = k;
        else memcpy(V + k * nq, dy, nq * sizeof(double));
    }
    RELEASE(dy);
    return failed;
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
static int dopri5(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout, const double *tout, double rtol, double atol,
                  double max_step, double first_step, double *Y, long *counts, double *fail, double *work) {
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
    double *y = work, *ynew = y + dim, *ys = ynew + dim, *err = ys + dim, *scale = err + dim, *f1 = scale + dim, *K[7];
    const size_t row = dim * sizeof(double);
    for (int s = 0; s < 7; s++) K[s] = f1 + (s + 1) * dim;
    long nfev = 0, nstep = 0, nrej = 0, o = 0;
    int rc;
    double t = t0, limit = 1.0;
    memcpy(y, y0, row);
    for (int i = 0; i < dim; i++) if (fabs(y[i]) > limit) limit = fabs(y[i]);
    limit *= 1e30;
    rc = f(ctx, t, y, K[0]); nfev++;
    if (rc) { fail_at(dim, fail, t, y); counts[0] = nfev; return rc; }
    while (o < nout && tout[o] <= t0) { memcpy(Y + o * dim, y, row); o++; }
    double h = first_step;
    if (!(h > 0.0)) {  /* scipy's select_initial_step, error order 4 */
        for (int i = 0; i < dim; i++) scale[i] = atol + fabs(y[i]) * rtol;
        double d0 = rms_scaled(dim, y, scale), d1 = rms_scaled(dim, K[0], scale), h0;
        h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
        if (h0 > t1 - t0) h0 = t1 - t0;
        for (int i = 0; i < dim; i++) ys[i] = y[i] + h0 * K[0][i];
        rc = f(ctx, t + h0, ys, f1); nfev++;
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
                rc = f(ctx, s == 6 ? tnew : t + C[s] * hstep, target, K[s]); nfev++;
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
            if (tout[o] == tnew) memcpy(Y + o * dim, ynew, row);
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
        memcpy(y, ynew, row);
        memcpy(K[0], K[6], row);
        nstep++;
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, t, y); counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return 4; }
    }
    counts[0] = nfev; counts[1] = nstep; counts[2] = nrej;
    return 0;
}

int lg_dopri5(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout, const double *tout, double rtol, double atol,
              double max_step, double first_step, double *Y, long *counts, double *fail) {
    double *work = malloc((size_t)13 * (dim > 0 ? dim : 1) * sizeof(double));
    if (!work) { fail_at(dim, fail, t0, y0); return 5; }
    int rc = dopri5(f, ctx, dim, t0, t1, y0, nout, tout, rtol, atol, max_step, first_step, Y, counts, fail, work);
    free(work);
    return rc;
}

/* Fixed steps t_k = t0 + k h, k = 1..N: method 0 classical Runge-Kutta, 1 Stormer-Verlet (kick-drift-kick;
   separable models only: A constant, b independent of the velocities). Outputs tout: a step's state when
   within 1e-7 h of it, else cubic Hermite interpolation between the neighbouring steps.
   Status as lg_dopri5 (4: diverged). */
static int fixed(rhs_fn f, const void *ctx, int nq, int dim, int method, double t0, double h, long N, const double *y0, long nout, const double *tout, double *Y,
                 long *counts, double *fail, double *work) {
    double *y = work, *ynew = y + dim, *fv = ynew + dim, *fnew = fv + dim, *k2 = fnew + dim, *k3 = k2 + dim, *k4 = k3 + dim, *ys = k4 + dim;
    const size_t row = dim * sizeof(double);
    long nfev = 0, o = 0;
    int rc;
    double limit = 1.0;
    memcpy(y, y0, row);
    for (int i = 0; i < dim; i++) if (fabs(y[i]) > limit) limit = fabs(y[i]);
    limit *= 1e30;
    rc = f(ctx, t0, y, fv); nfev++;
    if (rc) { fail_at(dim, fail, t0, y); counts[0] = nfev; return rc; }
    while (o < nout && (tout[o] - t0) / h < 1e-7) { memcpy(Y + o * dim, y, row); o++; }
    for (long k = 1; k <= N && o < nout; k++) {
        const double t = t0 + (k - 1) * h, tn = t0 + k * h;
        if (method == 0) {
            for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * fv[i];
            if ((rc = f(ctx, t + 0.5 * h, ys, k2))) { fail_at(dim, fail, t + 0.5 * h, ys); break; }
            for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * k2[i];
            if ((rc = f(ctx, t + 0.5 * h, ys, k3))) { fail_at(dim, fail, t + 0.5 * h, ys); break; }
            for (int i = 0; i < dim; i++) ys[i] = y[i] + h * k3[i];
            if ((rc = f(ctx, tn, ys, k4))) { fail_at(dim, fail, tn, ys); break; }
            for (int i = 0; i < dim; i++) ynew[i] = y[i] + h / 6.0 * (fv[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
            nfev += 3;
            if ((rc = f(ctx, tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); break; }
            nfev++;
        } else {  /* y = (q, v), f = (v, a): v += h/2 a; q += h v; a = a(q); v += h/2 a */
            for (int i = 0; i < nq; i++) { ynew[nq + i] = y[nq + i] + 0.5 * h * fv[nq + i]; ynew[i] = y[i] + h * ynew[nq + i]; }
            if ((rc = f(ctx, tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); break; }
            nfev++;
            for (int i = 0; i < nq; i++) { ynew[nq + i] += 0.5 * h * fnew[nq + i]; fnew[i] = ynew[nq + i]; }
        }
        while (o < nout && (tout[o] - t0) / h <= k + 1e-7) {
            double kf = (tout[o] - t0) / h;
            if (fabs(kf - k) < 1e-7) memcpy(Y + o * dim, ynew, row);
            else {
                double s = (tout[o] - t) / h, s2 = s * s, s3 = s2 * s;
                double h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2, h11 = s3 - s2;
                for (int i = 0; i < dim; i++)
                    Y[o * dim + i] = h00 * y[i] + h10 * h * fv[i] + h01 * ynew[i] + h11 * h * fnew[i];
            }
            o++;
        }
        memcpy(y, ynew, row);
        memcpy(fv, fnew, row);
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, tn, y); rc = 4; break; }
    }
    counts[0] = nfev; counts[1] = o;
    return rc;
}

int lg_fixed(rhs_fn f, const void *ctx, int nq, int dim, int method, double t0, double h, long N, const double *y0, long nout, const double *tout, double *Y,
             long *counts, double *fail) {
    double *work = malloc((size_t)8 * (dim > 0 ? dim : 1) * sizeof(double));
    if (!work) { fail_at(dim, fail, t0, y0); return 5; }
    int rc = fixed(f, ctx, nq, dim, method, t0, h, N, y0, nout, tout, Y, counts, fail, work);
    free(work);
    return rc;
}
"""



@functools.lru_cache(maxsize=1)
def _runtime_source() -> str:
    """The runtime library: the tape interpreter and the stepping loops (model-independent: compiled once per
    compiler and kept in the cache)."""
    return "\n".join([f"/* lagrangian.codegen {CODEGEN_VERSION}: runtime (tape interpreter, stepping loops); do not edit. */",
                      _HEADER, _SOLVE, _interpreter(), _LOOPS])


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


def _libraries(directory: Path, wanted: dict[str, tuple[str, str]], cc: str) -> dict[str, tuple[ctypes.CDLL, bool]]:
    """``{name: (library, from_cache)}`` for ``wanted`` ``{name: (key, source)}``: each from the cache, or
    compiled (all the missing ones at once, in parallel)."""
    found = {name: _load_cached(directory, key) for name, (key, _) in wanted.items()}
    missing = [name for name, lib in found.items() if lib is None]
    if missing:
        directory.mkdir(parents=True, exist_ok=True)
        jobs, failure = {}, None
        for name in missing:
            try:
                jobs[name] = _start(directory, *wanted[name], cc)
            except _Unavailable as exc:
                failure = failure or exc
        for name, job in jobs.items():  # finish every job started, even after a failure
            try:
                found[name] = _finish(directory, job, cc)
            except _Unavailable as exc:
                failure = failure or exc
        if failure is not None:
            raise failure
    return {name: (lib, name not in missing) for name, lib in found.items()}


def runtime() -> Path:
    """Build the runtime library (tape interpreter and stepping loops) now if it is not in the cache, and return
    its path — what an installation step or a container image would run once, so that no model ever waits for
    the C compiler unless it asks for native code.

    Raises :class:`~lagrangian.ModelError` with the reason when there is no
    usable C compiler or cache directory.
    """
    cc = compiler()
    if cc is None:
        raise ModelError("no C compiler found (none of cc, gcc, clang on the PATH, or LAGRANGIAN_CC); install one.")
    (directory, _), source = _cache(), _runtime_source()
    key = "runtime-" + _key(source, cc)
    try:
        _libraries(directory, {"runtime": (key, source)}, cc)
    except (_Unavailable, OSError) as exc:
        raise ModelError(f"the runtime library could not be built in {directory}: {exc}") from None
    return directory / f"{key}.so"


#: What ``compile_model`` can build: native code, the tape interpreter, or whichever is ready at once.
KINDS = ("native", "tape", "auto")


def compile_model(numeric, kind: str = "native") -> tuple[CompiledModel | None, str | None]:
    """``(CompiledModel, note)`` for ``numeric``, or ``(None, reason)`` when it cannot be compiled here; the note
    is ``None`` unless a private directory stood in for an untrusted cache directory (see :func:`cache_dir`).

    ``kind``: ``"native"`` — the model's tapes printed as C and compiled
    into a library of its own (from the cache when built before; else a C
    compilation of 0.1–0.5 s); ``"tape"`` — the tapes run by the runtime
    library's interpreter, which is the same for every model (compiled once
    per compiler, then cached), so nothing is compiled per model; ``"auto"``
    — the native library when it is already in the cache, else the tape.

    Never raises for a missing compiler, a failed compilation, an
    unwritable cache or callable signals: the reason comes back (and is
    logged) so that the caller can use the NumPy path.
    """
    if kind not in KINDS:
        raise ModelError(f"compile_model: kind must be one of {', '.join(map(repr, KINDS))}, not {kind!r}.")
    start = time.perf_counter()
    try:
        programs(numeric)
        source = generate_source(numeric) if kind != "tape" else None
        codegen_s = time.perf_counter() - start
        cc = compiler()
        if cc is None:
            wanted = _settings["compiler"] or os.environ.get("LAGRANGIAN_CC")
            raise _Unavailable(f"no C compiler found ({f'{wanted!r} is not a program on the PATH' if wanted else 'none of cc, gcc, clang on the PATH'}); "
                               f"install one or set LAGRANGIAN_CC")
        directory, cache_note = _cache()
        runtime = _runtime_source()
        libraries = {"runtime": ("runtime-" + _key(runtime, cc), runtime)}
        if source is not None:
            key = _key(source, cc)
            if kind == "native" or (directory / f"{key}.so").exists():
                libraries["model"] = (key, source)
        try:
            built = _libraries(directory, libraries, cc)
        except OSError as exc:
            raise _Unavailable(f"the cache directory {directory} is not usable ({exc}); set LAGRANGIAN_CACHE_DIR") from None
    except _Unavailable as exc:
        note = f"compiled code not used ({exc}): the NumPy path evaluates the model instead"
        _log.info(note)
        return None, note
    name = "model" if "model" in built else "runtime"
    lib, from_cache = built[name]
    try:
        compiled = CompiledModel(numeric, built["runtime"][0], lib if name == "model" else None, libraries[name][0],
                                 directory / f"{libraries[name][0]}.so", from_cache=from_cache, codegen_seconds=codegen_s,
                                 build_seconds=time.perf_counter() - start)
    except AttributeError as exc:  # a library without the functions it should have: not ours, or damaged
        note = (f"compiled code not used (the library in {directory} lacks {exc}; delete it to rebuild): the NumPy "
                f"path evaluates the model instead")
        _log.warning(note)
        return None, note
    return compiled, cache_note


class _Prog(ctypes.Structure):
    _fields_ = [("nin", ctypes.c_int), ("nconst", ctypes.c_int), ("ninstr", ctypes.c_int), ("nout", ctypes.c_int),
                ("consts", ctypes.c_void_p), ("code", ctypes.c_void_p), ("out", ctypes.c_void_p)]


class _Tape(ctypes.Structure):
    _fields_ = [("nq", ctypes.c_int), ("ni", ctypes.c_int), ("nf", ctypes.c_int), ("nm", ctypes.c_int),
                ("inertial", ctypes.c_void_p), ("first", ctypes.c_void_p), ("matrix", _Prog), ("energy", _Prog)]


def _array(values, dtype, keep: list) -> int:
    """The address of ``values`` as a C array (one element at least), the array kept alive in ``keep``."""
    a = np.ascontiguousarray(values if len(values) else [0], dtype=dtype)
    keep.append(a)
    return a.ctypes.data


def _prog(p: Program, keep: list) -> _Prog:
    """The interpreter's view of a tape, pointing into arrays kept alive in ``keep``."""
    return _Prog(p.n_inputs, len(p.constants), len(p.code), p.n_outputs, _array(p.constants, np.float64, keep),
                 _array(p.code.ravel(), np.int32, keep), _array(p.outputs, np.int32, keep))


def run_program(program: Program, inputs) -> np.ndarray:
    """Run a tape (:class:`lagrangian.tape.Program`) in the runtime library's C interpreter: ``inputs`` one row
    per evaluation (``N × n_inputs``, or one row), the outputs ``N × n_outputs`` (or one row).  The interpreter
    models run on, exposed for checking tapes against other evaluations.

    >>> import sympy as sp
    >>> from lagrangian.tape import record
    >>> x = sp.Symbol("x")
    >>> tape = record([sp.cos(x) ** 2 + sp.sin(x) ** 2, x ** 3], [x])
    >>> out = run_program(tape, [[0.5], [2.0]]) if compiler() else np.array([tape.evaluate([0.5]), tape.evaluate([2.0])])
    >>> out.round(12).tolist()                         # (the Python reference when there is no C compiler)
    [[1.0, 0.125], [1.0, 8.0]]
    """
    lib = ctypes.CDLL(str(runtime()))
    rows = np.atleast_2d(np.asarray(inputs, dtype=float))
    if rows.shape[1] != program.n_inputs:
        raise ModelError(f"run_program: the tape has {program.n_inputs} inputs, the rows have {rows.shape[1]}.")
    rows = np.ascontiguousarray(rows)
    keep: list = []
    prog = _prog(program, keep)
    out = np.empty((rows.shape[0], program.n_outputs))
    lib.lg_prog_eval.argtypes, lib.lg_prog_eval.restype = [ctypes.c_void_p, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p], ctypes.c_int
    if lib.lg_prog_eval(ctypes.addressof(prog), rows.shape[0], rows.ctypes.data, out.ctypes.data):
        raise NumericalError("run_program: out of memory for the tape's registers")
    return out if np.ndim(inputs) == 2 else out[0]


class CompiledModel:
    """The compiled functions of one :class:`~lagrangian.simulation.NumericModel` (see :func:`compile_model`).

    ``kind`` is ``"native"`` (the model's own library) or ``"tape"`` (its
    tapes run by the shared interpreter); ``from_cache`` says whether the
    library came from the disk cache (else it was just built); ``path`` is
    the library; ``key`` its cache key; ``codegen_seconds`` and
    ``build_seconds`` the time spent recording and printing the tapes and,
    in all, getting the library.
    """

    def __init__(self, numeric, runtime: ctypes.CDLL, lib: ctypes.CDLL | None, key: str, path: Path, *,
                 from_cache: bool, codegen_seconds: float, build_seconds: float):
        self.numeric, self.loops, self.lib, self.key, self.path = numeric, runtime, lib, key, path
        self.kind = "tape" if lib is None else "native"
        self.from_cache, self.codegen_seconds, self.build_seconds = from_cache, codegen_seconds, build_seconds
        self.n, self.nI, self.dim = numeric.n, numeric.nI, numeric.n + numeric.nI
        self.m = int(math.isqrt(len(numeric.eq.generic()["A"])))
        dbl, ptr, lng, cint = ctypes.c_double, ctypes.c_void_p, ctypes.c_long, ctypes.c_int
        if lib is not None:
            dims = (ctypes.c_int * 4)()
            lib.lg_dims(dims)
            if (dims[0], dims[1], dims[2]) != (self.n, self.nI, self.m):  # pragma: no cover - a stale or foreign library
                raise NumericalError(f"the compiled library {path} does not belong to this model; delete it and retry.")
            rhs, matrix, energies = lib.lg_rhs, lib.lg_matrix, lib.lg_energies
            self._ctx = None
        else:
            rhs, matrix, energies = runtime.lg_tape_rhs, runtime.lg_tape_matrix, runtime.lg_tape_energies
            self._ctx, self._keep = self._tape(numeric)
        rhs.argtypes, rhs.restype = [ptr, dbl, ptr, ptr], cint
        matrix.argtypes, matrix.restype = [ptr, dbl, ptr, ptr, ptr, ptr], cint
        energies.argtypes, energies.restype = [ptr, lng, ptr, ptr, ptr, ptr], None
        runtime.lg_velocities.argtypes, runtime.lg_velocities.restype = [ptr, ptr, cint, cint, lng, ptr, ptr, ptr], lng
        runtime.lg_dopri5.argtypes = [ptr, ptr, cint, dbl, dbl, ptr, lng, ptr, dbl, dbl, dbl, dbl, ptr, ptr, ptr]
        runtime.lg_dopri5.restype = cint
        runtime.lg_fixed.argtypes = [ptr, ptr, cint, cint, cint, dbl, dbl, lng, ptr, lng, ptr, ptr, ptr, ptr]
        runtime.lg_fixed.restype = cint
        self._rhs_c, self._matrix_c, self._energies_c = rhs, matrix, energies
        self._rhs_ptr = ctypes.cast(rhs, ctypes.c_void_p).value  # what the loops call
        self._local = threading.local()  # rhs() buffers, one pair per thread: a model may be shared by threads

    def _tape(self, numeric) -> tuple[int, list]:
        """The interpreter's description of this model (a C struct pointing into arrays kept alive here)."""
        eq = numeric.eq
        keep: list = []
        matrix, energy = programs(numeric)
        tape = _Tape(self.n, self.nI, len(eq.first_order), self.m, _array(eq.inertial, np.int32, keep),
                     _array(list(eq.first_order), np.int32, keep), _prog(matrix, keep), _prog(energy, keep))
        keep.append(tape)
        return ctypes.addressof(tape), keep

    def describe(self) -> str:
        """What evaluates the model: ``native code (<key>.so, from the cache)`` or ``the tape interpreter (…)``."""
        if self.kind == "native":
            return f"native code ({self.path.name}{', from the cache' if self.from_cache else ', built now'})"
        matrix, _ = programs(self.numeric)
        return f"the tape interpreter ({len(matrix.code)} instructions per evaluation; nothing compiled for this model)"

    # -- one state ----------------------------------------------------------------
    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``dy/dt`` at ``(t, y)``, ``y = (q, q̇_inertial)``: the same as ``NumericModel.rhs``, in C."""
        buffers = getattr(self._local, "buffers", None)
        if buffers is None:
            y_in, dy_out = np.zeros(max(self.dim, 1)), np.zeros(max(self.dim, 1))
            buffers = self._local.buffers = (y_in, dy_out, y_in.ctypes.data, dy_out.ctypes.data)
        y_in, dy_out, yp, dyp = buffers
        y_in[: self.dim] = y
        rc = self._rhs_c(self._ctx, t, yp, dyp)
        if rc:
            self._raise(rc, t, y_in[: self.dim].copy())
        return dy_out[: self.dim].copy()

    def matrix(self, t: float, q: np.ndarray, vI: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``A`` and ``b`` of the solve ``A u = b`` at ``(t, q, q̇_inertial)``."""
        A, b = np.zeros((self.m, self.m)), np.zeros(self.m)
        q = np.ascontiguousarray(q, dtype=float)
        vI = np.ascontiguousarray(vI, dtype=float)
        self._matrix_c(self._ctx, t, q.ctypes.data, vI.ctypes.data if vI.size else None, A.ctypes.data, b.ctypes.data)
        return A, b

    def _raise(self, rc: int, t: float, y: np.ndarray):
        if rc == 1:
            A, _ = self.matrix(t, y[: self.n], y[self.n :])
            raise SingularMassMatrixError(self.numeric._singular_message(t, A, y[: self.n]))
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
        k = self.loops.lg_velocities(self._rhs_ptr, self._ctx, self.n, self.dim, times.size, times.ctypes.data, rows.ctypes.data,
                                     out.ctypes.data)
        if k >= 0:
            dy = np.empty(self.dim)
            self._raise(self._rhs_c(self._ctx, times[k], rows[k].ctypes.data, dy.ctypes.data) or 2, times[k], rows[k])
        return out.T.copy()

    def _energies(self, times, q, v) -> np.ndarray:
        times = np.ascontiguousarray(np.broadcast_to(np.asarray(times, dtype=float), (np.shape(q)[1],)))
        qr = np.ascontiguousarray(np.asarray(q, dtype=float).T)
        vr = np.ascontiguousarray(np.asarray(v, dtype=float).T)
        out = np.empty((times.size, 4))
        self._energies_c(self._ctx, times.size, times.ctypes.data, qr.ctypes.data, vr.ctypes.data, out.ctypes.data)
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
            5: f"{what}: out of memory for the stepping loop's {13 * self.dim} numbers",
        }[status]

    def dopri5(self, t_span, y0, t_eval, *, rtol: float, atol: float, max_step: float, first_step: float | None):
        """Dormand–Prince 5(4) in C from ``y0``; ``(Y (dim × len), nfev, status, message)``; output stops at a failure."""
        t_eval = np.ascontiguousarray(t_eval, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        Y = np.full((t_eval.size, self.dim), np.nan)
        counts = np.zeros(3, dtype=np.int64)  # long is 64-bit on the platforms we build on
        fail = np.zeros(self.dim + 1)
        status = self.loops.lg_dopri5(self._rhs_ptr, self._ctx, self.dim, float(t_span[0]), float(t_span[1]), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
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
        status = self.loops.lg_fixed(self._rhs_ptr, self._ctx, self.n, self.dim, code, float(t0), float(h), int(N), y0.ctypes.data, t_eval.size, t_eval.ctypes.data,
                                   Y.ctypes.data, counts.ctypes.data, fail.ctypes.data)
        message = self._run(status, fail, method) if status else ""
        return Y.T, int(counts[0]), message
