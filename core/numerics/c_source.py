"""C source of compiled models: the tapes of a model (:func:`programs`) printed as straight-line C
(:func:`generate_source`), and the runtime library's C — the tape interpreter, the dense LU solve and the stepping
loops — that is the same for every model.  Names enter the C only through :func:`c_comment`.
"""

from __future__ import annotations

import functools

from ..base.component import t as time_symbol
from ..derivation.calculus import dense

from .band import BAND_MATRIX, BAND_RUNTIME, BAND_SOLVE, NATIVE_BAND_RHS, Band, band_of, native_tables, recursive_arrays, solve_size
from .c_dop853 import ENSEMBLE_SOURCE, dop853_source
from .tape import OPS, Program, TapeError, c_body, record
from ..base import deferred as _deferred

sp = _deferred.module("sympy", globals())

#: Bumped whenever the generated C changes shape, so that old cache entries are not reused.
CODEGEN_VERSION = "9"


class _Unavailable(Exception):
    """The model cannot be compiled here; the message says why (turned into a note, never raised to the user)."""


def _arrays(numeric) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    """The entries of ``A`` and ``b``, and ``T, V, D, L`` and the momenta ``p = ∂L/∂q̇`` (for the Jacobi integral
    ``h = p·q̇ − L``), generic: every parameter with a value (given as a number or by ``params=``) a symbol."""
    return _arrays_of(numeric.eq)


def _arrays_of(eq) -> tuple[list[sp.Expr], list[sp.Expr], list[sp.Expr]]:
    if eq.recursion is not None:
        return recursive_arrays(eq)
    g = eq.generic()
    energies = [g["T"], g["V"], g["D"], g["L"], *g["p"]]
    return dense(g["A"]), dense(g["b"]), energies


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


def programs(numeric, banded: bool | None = None) -> tuple[Program, Program]:
    """The two tapes (:mod:`lagrangian.tape`) of ``numeric``: ``A`` and ``b`` from ``(t, q, q̇_inertial)``, and
    ``T, V, D, L, p`` from ``(t, q, q̇)``, with ``numeric``'s parameter values in their constant registers.

    The tapes are recorded once per model (kept on its equations), with the
    parameters as registers whose values are put in for each set of values
    (:meth:`lagrangian.tape.Program.with_values`): new values record
    nothing again, and the tape interpreter runs them at once.

    Raises an internal error (turned into a note by :func:`compile_model`)
    when the model cannot be compiled: time signals given as Python
    callables, or functions the tape does not know.

    ``banded``: whether the tape of ``A`` records its nonzero entries only, in the order of
    :func:`band_of`'s pattern (``None``: when the model's solve is banded; ``False``: ``A`` whole, row-major).
    """
    if banded is None:
        banded = band_of(numeric.eq) is not None
    found = numeric.__dict__.setdefault("_tapes_by_layout", {})
    if banded in found:
        return found[banded]
    generic = _generic_programs(numeric.eq, tuple(sorted(numeric.values, key=sp.default_sort_key)), banded)
    try:
        found[banded] = tuple(p.with_values(numeric.values) for p in generic)
    except TapeError as exc:  # pragma: no cover - every parameter has a value by Model._values
        raise _Unavailable(str(exc)) from None
    return found[banded]


def _generic_programs(eq, parameters: tuple, banded: bool = False) -> tuple[Program, Program]:
    """The tapes of ``eq`` with ``parameters`` as run-time constants, recorded once per set of parameter symbols
    (``banded``: ``A``'s nonzero entries only, see :func:`programs`)."""
    cache = eq.__dict__.setdefault("_generic_tapes", {})
    if (parameters, banded) in cache:
        return cache[parameters, banded]
    if eq.recursion is not None:  # (A's nonzero entries, its diagonal, in either layout)
        a_entries, b_entries, energies = recursive_arrays(eq)
    elif banded:
        g = eq.generic()
        A = g["A"]
        a_entries, b_entries = [A[i, j] for i, j in band_of(eq).pattern], dense(g["b"])
        energies = [g["T"], g["V"], g["D"], g["L"], *g["p"]]
    else:
        a_entries, b_entries, energies = _arrays_of(eq)
    scan = eq.scan()
    callables = scan["callables"]
    if callables or scan["derivatives"]:
        raise _Unavailable(
            f"the model uses signals or loads given as Python callables ({', '.join(callables) or 'derivatives'}), "
            f"which compiled code cannot call; give them as SymPy expressions (of t, or of the state for a load) to "
            f"compile"
        )
    q, v = list(eq.sym.q), list(eq.sym.v)
    steps = eq.recursion.recursion.definitions if eq.recursion is not None else ()
    try:
        matrix = record([*a_entries, *b_entries], [time_symbol, *q, *(v[i] for i in eq.inertial)], parameters, steps)
        energy = record(energies, [time_symbol, *q, *v], parameters, steps)
    except TapeError as exc:
        raise _Unavailable(str(exc)) from None
    cache[parameters, banded] = (matrix, energy)
    return cache[parameters, banded]


def generate_source(numeric) -> str:
    """The C source of ``numeric``'s native library (a :class:`~lagrangian.simulation.NumericModel`):
    its tapes (:func:`programs`) printed as straight-line C — ``lg_matrix`` (the entries of ``A`` and ``b``),
    ``lg_rhs`` (that and the LU solve: the state derivative) and ``lg_energies`` (``T``, ``V``, ``D``,
    Jacobi integral); the stepping loops are in the runtime library, shared by every model.
    """
    return _source(numeric.eq, *programs(numeric), band=band_of(numeric.eq))


def parametric_source(eq, parameters: tuple) -> str:
    """The C source of a native library of ``eq`` that reads the values of ``parameters`` (symbols) at run time,
    from the array its functions get as ``ctx`` (``P[k]``: the value of ``parameters[k]``): one library for every
    set of values, as the tape interpreter is (``lagrangian.numerics.ensemble`` runs many sets with it).  What
    depends on the parameters alone is computed per evaluation rather than folded away."""
    matrix, energy = _generic_programs(eq, parameters)
    return _source(eq, matrix, energy, parameters, band=band_of(eq) if eq.recursion is not None else None)


def _source(eq, matrix: Program, energy: Program, parameters: tuple | None = None, band: Band | None = None) -> str:
    n, nI = len(eq.sym.q), len(eq.inertial)
    first = list(eq.first_order)
    m = solve_size(eq)
    inputs_m = {0: "t", **{1 + i: f"q[{i}]" for i in range(n)}, **{1 + n + j: f"vI[{j}]" for j in range(nI)}}
    inputs_e = {0: "t", **{1 + i: f"q[{i}]" for i in range(n)}, **{1 + n + i: f"v[{i}]" for i in range(n)}}
    if parameters is not None:  # the parameters' constant registers read P (= ctx)
        slot = {s: k for k, s in enumerate(parameters)}
        inputs_m |= {matrix.n_inputs + i: f"P[{slot[s]}]" for s, i in matrix.parameters.items()}
        inputs_e |= {energy.n_inputs + i: f"P[{slot[s]}]" for s, i in energy.parameters.items()}
    entries = m * m if band is None else len(band.pattern)  # (banded: A's nonzero entries, in the band's order)
    parts_m, body_m = c_body(matrix, inputs_m, [f"A[{k}]" for k in range(entries)] + [f"b[{k}]" for k in range(m)],
                            "matrix_part", "const double *P, double t, const double *q, const double *vI, double *A, "
                            "double *b", "P, t, q, vI, A, b", ["for (int k = 0; k < NM; k++) b[k] = NAN;", "return 2;"],
                            zeroed=True)
    parts_e, body_e = c_body(energy, inputs_e, [f"o[{k}]" for k in range(4 + n)], "energy_part",
                            "const double *P, double t, const double *q, const double *v, double *o", "P, t, q, v, o",
                            ["for (int k = 0; k < 4 + NQ; k++) o[k] = NAN;", "return;"])

    def table(values):
        return "{" + ", ".join(map(str, values or [0])) + "}"

    return "\n".join([
        c_comment(f"Generated by lagrangian.codegen {CODEGEN_VERSION}; coordinates {', '.join(eq.names)}; "
                  f"{'parameters read at run time' if parameters is not None else 'parameter values built in'}; "
                  f"do not edit."),
        _HEADER,
        f"#define NQ {n}",
        f"#define NI {nI}",
        f"#define NF {len(first)}",
        f"#define NM {m}",
        f"#define NP {len(parameters) if parameters is not None else -1}",
        f"static const int INERTIAL[] = {table(eq.inertial)};",
        f"static const int FIRST[] = {table(first)};",
        _SOLVE,
        "int lg_dims(int *out) { out[0] = NQ; out[1] = NI; out[2] = NM; out[3] = NF; out[4] = NP; return 0; }",
        "",
        *(native_tables(band, table) if band is not None else []),
        *parts_m,
        "/* The entries of A (row-major, NM x NM; banded: its NNZ nonzero entries, in the order of ROW and COL) and b",
        "   of the solve A u = b, u = (accelerations, first-order rates, multipliers).",
        "   Static, so that lg_rhs calls it directly (an exported function is called through the PLT) or inlines it. */",
        "static int matrix_terms(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {",
        "    const double *P = ctx; (void)P;",
        *([f"    memset(A, 0, sizeof(double) * {'NM * NM' if band is None else 'NNZ'});",
           "    memset(b, 0, sizeof(double) * NM);"]
          if matrix.zero_outputs(inputs_m) else []),  # (a dense matrix, a double pendulum's, is written whole)
        *body_m,
        "    return 0;",
        "}",
        "",
        *(_DENSE_MATRIX if band is None else BAND_MATRIX),
        "",
        *parts_e,
        "/* T, V, D, L and the momenta p at (t, q, v), v: the rates of all coordinates. */",
        "static void energy_terms(const double *P, double t, const double *q, const double *v, double *o) {",
        "    (void)P;",
        *body_e,
        "}",
        _NATIVE if band is None else _NATIVE_BAND,
    ]) + "\n"


_DENSE_MATRIX = ["int lg_matrix(const void *ctx, double t, const double *q, const double *vI, double *A, double *b) {",
                 "    return matrix_terms(ctx, t, q, vI, A, b);",
                 "}"]


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
static int lu_core(int nm, double *A, double *b) {
    double amax = 0.0;
    for (int i = 0; i < nm * nm; i++) {
        double a = fabs(A[i]);
        if (!(a <= DBL_MAX)) return 2;
        if (a > amax) amax = a;
    }
    const double tiny = nm * DBL_EPSILON * amax;
    if (nm && !(amax > 0.0)) return 1;
    if (nm == 2) {
        /* In closed form: one division where the elimination chains three (9 % of a double pendulum's run).  The
           verdict is elimination's: its pivots are p and det / p. */
        const double a = A[0], c = A[1], d = A[2], e = A[3];
        const double p = fabs(a) > fabs(d) ? fabs(a) : fabs(d), det = a * e - c * d;  /* (fmax is a call) */
        if (!(p > tiny) || !(fabs(det) > tiny * p)) return det == det ? 1 : 2;
        const double inv = 1.0 / det, x = (e * b[0] - c * b[1]) * inv, y = (a * b[1] - d * b[0]) * inv;
        b[0] = x;
        b[1] = y;
        return 0;
    }
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

/* The unknowns of the constraints (the last nc of the nm: their multipliers) scaled by powers of two, D A D y = D b
   and u = D y, so that each constraint's row (and the multiplier's column) is as large as the largest entry of the
   rest of A: a constraint written with a factor 1e-9 or 1e30 is the same constraint, and the singularity test
   (pivots against nm eps max|A|) judges its solve alike.  The powers of two scale exactly.  s: nc factors. */
static void balance(int nm, int nc, double *A, double *b, double *s) {
    const int k = nm - nc;
    double mu = 0.0;
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) { const double a = fabs(A[i * nm + j]); if (a > mu) mu = a; }
    int emu = 0;
    frexp(mu, &emu);
    for (int r = 0; r < nc; r++) {
        double row = 0.0;
        for (int j = 0; j < nm; j++) { const double a = fabs(A[(k + r) * nm + j]); if (a > row) row = a; }
        s[r] = 1.0;
        if (mu > 0.0 && mu <= DBL_MAX && row > 0.0 && row <= DBL_MAX) {
            int er = 0;
            frexp(row, &er);
            int e = emu - er;
            s[r] = ldexp(1.0, e > 1000 ? 1000 : e < -1000 ? -1000 : e);
        }
    }
    for (int r = 0; r < nc; r++) {
        const double f = s[r];
        if (f == 1.0) continue;
        for (int j = 0; j < nm; j++) A[(k + r) * nm + j] *= f;
        for (int i = 0; i < nm; i++) A[i * nm + k + r] *= f;
        b[k + r] *= f;
    }
}

/* A u = b solved in place (b becomes u), the last nc unknowns being multipliers of constraints (balance). */
static int lu_solve(int nm, int nc, double *A, double *b) {
    if (nc <= 0 || nc >= nm) return lu_core(nm, A, b);
    double s_stack[64];
    double *s = nc <= 64 ? s_stack : malloc((size_t)nc * sizeof(double));
    if (!s) return 2;
    balance(nm, nc, A, b, s);
    const int rc = lu_core(nm, A, b);
    if (!rc) for (int r = 0; r < nc; r++) b[nm - nc + r] *= s[r];
    if (s != s_stack) free(s);
    return rc;
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

# The native library's entry points (its sizes are constants; ctx is the parameters' values when they are read at
# run time, else unused: the functions are the model).
_NATIVE = r"""
int lg_rhs(const void *ctx, double t, const double *y, double *dy) {
    SCRATCH(A, NM * NM + NM + 1);
    if (!A) return 2;
    double *b = A + NM * NM;
    matrix_terms(ctx, t, y, y + NQ, A, b);
    int rc = lu_solve(NM, NM - NI - NF, A, b);
    if (!rc) rc = state_rate(NQ, NI, NF, INERTIAL, FIRST, y, b, dy);
    RELEASE(A);
    return rc;
}

void lg_energies(const void *ctx, long N, const double *t, const double *q, const double *v, double *out) {
    SCRATCH(o, 4 + NQ);
    for (long k = 0; k < N; k++) {
        if (!o) { for (int i = 0; i < 4; i++) out[4 * k + i] = NAN; continue; }
        energy_terms(ctx, t[k], q + k * NQ, v + k * NQ, o);
        energy_out(NQ, v + k * NQ, o, out + 4 * k);
    }
    RELEASE(o);
}
"""


# A banded native library's state derivative, and its energies as a dense one's.
_NATIVE_BAND = NATIVE_BAND_RHS + _NATIVE[_NATIVE.index("void lg_energies"):]


def _interpreter() -> str:
    """The C interpreter of tapes: one ``case`` per operation of :data:`lagrangian.tape.OPS`."""
    cases = "\n".join(f"        case {k}: r[c[1]] = {template}; break;" for k, (_, template) in enumerate(OPS.values()))
    labels = ", ".join(f"&&op{k}" for k in range(len(OPS)))
    threaded = "\n".join(f"    op{k}: {{ const double x = r[c[2]], y = r[c[3]], z = r[c[4]]; (void)y; (void)z; "
                         f"r[c[1]] = {template}; c += 5; if (c == end) return; goto *ops[c[0]]; }}"
                         for k, (_, template) in enumerate(OPS.values()))
    return r"""
/* A tape (lagrangian.tape.Program): registers = inputs, constants, temporaries; rows (op, dst, x, y, z). */
typedef struct { int nin, nconst, ninstr, nout; const double *consts; const int *code; const int *out; } lg_prog;
/* A model as two tapes: A and b from (t, q, q'_inertial); T, V, D, L, p from (t, q, q'). */
typedef struct { int nq, ni, nf, nm; const int *inertial, *first; lg_prog matrix, energy; } lg_tape;

#if defined(__GNUC__)
/* Direct threading (GCC and Clang's labels as values): each operation jumps straight to the next one's code, so
   the processor predicts every jump from where it is taken, not one shared switch (1.25x on the 4,729
   operations of three bodies on spherical joints: benchmarks/spatial.py). */
static void run(const lg_prog *p, double *r) {
    static const void *const ops[] = {""" + labels + r"""};
    memcpy(r + p->nin, p->consts, p->nconst * sizeof(double));
    const int *c = p->code, *const end = p->code + 5 * p->ninstr;
    if (c == end) return;
    goto *ops[c[0]];
""" + threaded + r"""
}
#else
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
#endif

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
    if (!rc) rc = lu_solve(nm, nm - m->ni - m->nf, o, o + nm * nm);
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

/* s moved inside the run from a to b by 16 units in the last place at either end: an input that switches at a or b
   (a pulse's corner, where an adaptive run restarts) is read on this run's side of its corner, not the next one's
   (the last stage of a step that ends at b feeds the step's dense output). */
static double inside(double s, double a, double b) {
    const double ma = 16.0 * (nextafter(fabs(a), INFINITY) - fabs(a)), mb = 16.0 * (nextafter(fabs(b), INFINITY) - fabs(b));
    if (!(b - a > 4.0 * (ma + mb))) return s;
    return s < a + ma ? a + ma : s > b - mb ? b - mb : s;
}

/* After a step of an adaptive run to t: 6 where at its pace the run would need more than budget evaluations
   (judged from 131,072 on; budget 0: never), 7 where another thread asked it to stop (watch[1] set; watch[0] gets
   the time reached); else 0.  watch may be NULL. */
static int watched(int dim, double t0, double t1, double t, const double *y, long nfev, double budget,
                   volatile double *watch, double *fail) {
    if (budget > 0 && nfev >= 131072 && nfev * ((t1 - t0) / (t - t0)) > budget) { fail_at(dim, fail, t, y); return 6; }
    if (watch) { watch[0] = t; if (watch[1] != 0.0) { fail_at(dim, fail, t, y); return 7; } }
    return 0;
}

/* y = y0, and the size past which an adaptive run's state counts as diverged: 1e30 times y0's (at least 1). */
static double start_state(int dim, double *y, const double *y0) {
    double limit = 1.0;
    memcpy(y, y0, dim * sizeof(double));
    for (int i = 0; i < dim; i++) if (fabs(y[i]) > limit) limit = fabs(y[i]);
    return limit * 1e30;
}

/* Dormand-Prince 5(4) (as scipy's RK45): the tableau, the error weights and the quartic dense output. */
static const double DP_C[7] = {0.0, 1.0 / 5, 3.0 / 10, 4.0 / 5, 8.0 / 9, 1.0, 1.0};
static const double DP_A[7][6] = {
    {0}, {1.0 / 5}, {3.0 / 40, 9.0 / 40}, {44.0 / 45, -56.0 / 15, 32.0 / 9},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656},
    {35.0 / 384, 0.0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784, 11.0 / 84}};
static const double DP_E[7] = {-71.0 / 57600, 0.0, 71.0 / 16695, -71.0 / 1920, 17253.0 / 339200, -22.0 / 525, 1.0 / 40};
static const double DP_P[7][4] = {
    {1.0, -8048581381.0 / 2820520608, 8663915743.0 / 2820520608, -12715105075.0 / 11282082432},
    {0.0, 0.0, 0.0, 0.0},
    {0.0, 131558114200.0 / 32700410799, -68118460800.0 / 10900136933, 87487479700.0 / 32700410799},
    {0.0, -1754552775.0 / 470086768, 14199869525.0 / 1410260304, -10690763975.0 / 1880347072},
    {0.0, 127303824393.0 / 49829197408, -318862633887.0 / 49829197408, 701980252875.0 / 199316789632},
    {0.0, -282668133.0 / 205662961, 2019193451.0 / 616988883, -1453857185.0 / 822651844},
    {0.0, 40617522.0 / 29380423, -110615467.0 / 29380423, 69997945.0 / 29380423}};

/* The work array of a Dormand-Prince run (13 dim numbers): y, ynew, ys, err, scale, f1, then the stages K[0..6]. */
#define DP_WORK 13
static void dp_stages(int dim, double *work, double **K) { for (int s = 0; s < 7; s++) K[s] = work + (6 + s) * dim; }

/* K[0] = f(t0, y) and the first step to try (first_step, or scipy's select_initial_step, error order 4). */
static int dp_begin(rhs_fn f, const void *ctx, int dim, double t0, double t1, double rtol, double atol, double first_step,
                    double *work, double *h, long *nfev, double *fail) {
    double *y = work, *ys = y + 2 * dim, *err = y + 3 * dim, *scale = y + 4 * dim, *f1 = y + 5 * dim, *K[7];
    dp_stages(dim, work, K);
    int rc = f(ctx, inside(t0, t0, t1), y, K[0]); (*nfev)++;
    if (rc) { fail_at(dim, fail, t0, y); return rc; }
    *h = first_step;
    if (*h > 0.0) return 0;
    for (int i = 0; i < dim; i++) scale[i] = atol + fabs(y[i]) * rtol;
    double d0 = rms_scaled(dim, y, scale), d1 = rms_scaled(dim, K[0], scale), h0;
    h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
    if (h0 > t1 - t0) h0 = t1 - t0;
    for (int i = 0; i < dim; i++) ys[i] = y[i] + h0 * K[0][i];
    rc = f(ctx, t0 + h0, ys, f1); (*nfev)++;
    double d2 = 0.0;
    if (!rc) { for (int i = 0; i < dim; i++) err[i] = f1[i] - K[0][i]; d2 = rms_scaled(dim, err, scale) / h0; }
    double dm = d1 > d2 ? d1 : d2, h1;
    h1 = (dm <= 1e-15) ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / dm, 1.0 / 5.0);
    *h = fmin(100 * h0, h1);
    if (*h > t1 - t0) *h = t1 - t0;
    return 0;
}

/* One accepted step from (t, y) with K[0] = f(t, y), trying *h first (rejected tries shrink it): on return ynew and
   the stages K belong to the step of length *hstep, ending at *tend; *h is the next step to try.  y and K[0] are not yet advanced
   (the dense output needs them): dp_shift does that.  Status 0, or 1 singular matrix, 3 step size too small. */
static int dp_step(rhs_fn f, const void *ctx, int dim, double t, double t1, double rtol, double atol, double max_step,
                   double *work, double *h, double *hstep, double *tend, long *nfev, long *nrej, double *fail) {
    const double SAFETY = 0.9, MIN_FACTOR = 0.2, MAX_FACTOR = 10.0;
    double *y = work, *ynew = y + dim, *ys = y + 2 * dim, *err = y + 3 * dim, *scale = y + 4 * dim, *K[7];
    dp_stages(dim, work, K);
    double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
    if (*h > max_step) *h = max_step;
    if (*h < min_step) *h = min_step;
    int rejected = 0, rc;
    for (;;) {
        if (*h < min_step) { fail_at(dim, fail, t, y); return 3; }
        double tnew = t + *h;
        if (tnew > t1) tnew = t1;
        *hstep = tnew - t;
        *tend = tnew;
        int bad = 0;
        for (int s = 1; s < 7 && !bad; s++) {
            double *target = (s == 6) ? ynew : ys;
            for (int i = 0; i < dim; i++) {
                double acc = 0.0;
                for (int j = 0; j < s; j++) acc += DP_A[s][j] * K[j][i];
                target[i] = y[i] + *hstep * acc;
            }
            rc = f(ctx, s == 6 ? inside(tnew, t, t1) : t + DP_C[s] * *hstep, target, K[s]); (*nfev)++;
            if (rc == 1) { fail_at(dim, fail, t + DP_C[s] * *hstep, target); return 1; }
            if (rc) bad = 1;
        }
        double norm;
        if (bad) norm = INFINITY;
        else {
            for (int i = 0; i < dim; i++) {
                double acc = 0.0;
                for (int j = 0; j < 7; j++) acc += DP_E[j] * K[j][i];
                err[i] = *hstep * acc;
                scale[i] = atol + (fabs(y[i]) > fabs(ynew[i]) ? fabs(y[i]) : fabs(ynew[i])) * rtol;
            }
            norm = rms_scaled(dim, err, scale);
            if (!(norm == norm)) norm = INFINITY;
        }
        if (norm < 1.0) {
            double factor = norm == 0.0 ? MAX_FACTOR : fmin(MAX_FACTOR, SAFETY * pow(norm, -0.2));
            if (rejected && factor > 1.0) factor = 1.0;
            *h = *hstep * factor;
            return 0;
        }
        *h = *hstep * fmax(MIN_FACTOR, norm == INFINITY ? MIN_FACTOR : SAFETY * pow(norm, -0.2));
        rejected = 1;
        (*nrej)++;
    }
}

/* The quartic dense output of the last step (from t_old, length hstep) at x = (s - t_old) / hstep. */
static void dp_dense(int dim, const double *work, double hstep, double x, double *out) {
    const double *y = work, *K[7];
    for (int s = 0; s < 7; s++) K[s] = work + (6 + s) * dim;
    double w[4] = {x, x * x, x * x * x, x * x * x * x};
    for (int i = 0; i < dim; i++) {
        double acc = 0.0;
        for (int j = 0; j < 7; j++) {
            if (j == 1) continue;
            acc += K[j][i] * (DP_P[j][0] * w[0] + DP_P[j][1] * w[1] + DP_P[j][2] * w[2] + DP_P[j][3] * w[3]);
        }
        out[i] = y[i] + hstep * acc;
    }
}

static void dp_shift(int dim, double *work) {  /* y = ynew, K[0] = K[6] (first same as last) */
    memcpy(work, work + dim, dim * sizeof(double));
    memcpy(work + 6 * dim, work + 12 * dim, dim * sizeof(double));
}

/* Dormand-Prince 5(4) with error control (as scipy's RK45) and its quartic dense output on tout.
   Status: 0 done; 1 singular matrix, 2 not finite, 3 step size too small, 4 diverged, 6 over budget, 7 stopped
   (state at fail); budget and watch as for lg_dop853. */
static int dopri5(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout, const double *tout, double rtol, double atol,
                  double max_step, double first_step, double budget, volatile double *watch, double *Y, long *counts,
                  double *fail, double *work) {
    double *y = work, *ynew = y + dim;
    const size_t row = dim * sizeof(double);
    long nfev = 0, nstep = 0, nrej = 0, o = 0;
    double t = t0, limit = start_state(dim, y, y0), h, hstep, tnew;
    int rc = dp_begin(f, ctx, dim, t0, t1, rtol, atol, first_step, work, &h, &nfev, fail);
    if (rc) { counts[0] = nfev; return rc; }
    while (o < nout && tout[o] <= t0) { memcpy(Y + o * dim, y, row); o++; }
    while (t < t1) {
        rc = dp_step(f, ctx, dim, t, t1, rtol, atol, max_step, work, &h, &hstep, &tnew, &nfev, &nrej, fail);
        if (rc) { counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return rc; }
        while (o < nout && tout[o] <= tnew) {
            if (tout[o] == tnew) memcpy(Y + o * dim, ynew, row);
            else dp_dense(dim, work, hstep, (tout[o] - t) / hstep, Y + o * dim);
            o++;
        }
        t = tnew;
        dp_shift(dim, work);
        nstep++;
        if (!bounded(dim, y, limit)) { fail_at(dim, fail, t, y); counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return 4; }
        rc = watched(dim, t0, t1, t, y, nfev, budget, watch, fail);
        if (rc) { counts[0] = nfev; counts[1] = nstep; counts[2] = nrej; return rc; }
    }
    counts[0] = nfev; counts[1] = nstep; counts[2] = nrej;
    return 0;
}

int lg_dopri5(rhs_fn f, const void *ctx, int dim, double t0, double t1, const double *y0, long nout, const double *tout, double rtol, double atol,
              double max_step, double first_step, double budget, double *watch, double *Y, long *counts, double *fail) {
    double *work = malloc((size_t)DP_WORK * (dim > 0 ? dim : 1) * sizeof(double));
    if (!work) { fail_at(dim, fail, t0, y0); return 5; }
    int rc = dopri5(f, ctx, dim, t0, t1, y0, nout, tout, rtol, atol, max_step, first_step, budget, watch, Y, counts, fail,
                    work);
    free(work);
    return rc;
}

/* Dormand-Prince one step at a time, for drivers that stop between steps (events).  work: DP_WORK * dim numbers
   owned by the caller, y0 in its first dim.  lg_dopri5_begin evaluates K[0] and the first step *h; each
   lg_dopri5_step (shift = 0 the first time, then 1: y and K[0] move on to the last step's end) takes one accepted
   step from t and leaves y (its start), ynew (work + dim, its end at *tend) and the stages for lg_dopri5_dense.
   counts: nfev, nrej (added to).  Status as lg_dopri5. */
int lg_dopri5_begin(rhs_fn f, const void *ctx, int dim, double t0, double t1, double rtol, double atol, double first_step,
                    double *work, double *h, long *counts, double *fail) {
    return dp_begin(f, ctx, dim, t0, t1, rtol, atol, first_step, work, h, counts, fail);
}

int lg_dopri5_step(rhs_fn f, const void *ctx, int dim, int shift, double t, double t1, double rtol, double atol, double max_step,
                   double *work, double *h, double *hstep, double *tend, long *counts, double *fail) {
    if (shift) dp_shift(dim, work);
    return dp_step(f, ctx, dim, t, t1, rtol, atol, max_step, work, h, hstep, tend, counts, counts + 1, fail);
}

void lg_dopri5_dense(int dim, const double *work, double hstep, double x, double *out) { dp_dense(dim, work, hstep, x, out); }

/* One fixed step from (t, y) with fv = f(t, y) to tn = t + h: ynew and fnew = f(tn, ynew) (for Runge-Kutta only
   with tail: the next step's first stage), in the work array (y, ynew, fv, fnew, k2, k3, k4, ys).  Method 0
   classical Runge-Kutta, 1 Stormer-Verlet. */
static int fixed_step(rhs_fn f, const void *ctx, int nq, int dim, int method, double t, double tn, double h, double *work,
                      int tail, long *nfev, double *fail) {
    double *y = work, *ynew = y + dim, *fv = ynew + dim, *fnew = fv + dim, *k2 = fnew + dim, *k3 = k2 + dim, *k4 = k3 + dim, *ys = k4 + dim;
    int rc;
    if (method == 0) {
        for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * fv[i];
        if ((rc = f(ctx, t + 0.5 * h, ys, k2))) { fail_at(dim, fail, t + 0.5 * h, ys); return rc; }
        for (int i = 0; i < dim; i++) ys[i] = y[i] + 0.5 * h * k2[i];
        if ((rc = f(ctx, t + 0.5 * h, ys, k3))) { fail_at(dim, fail, t + 0.5 * h, ys); return rc; }
        for (int i = 0; i < dim; i++) ys[i] = y[i] + h * k3[i];
        if ((rc = f(ctx, tn, ys, k4))) { fail_at(dim, fail, tn, ys); return rc; }
        for (int i = 0; i < dim; i++) ynew[i] = y[i] + h / 6.0 * (fv[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        *nfev += 3;
        if (!tail) return 0;
        if ((rc = f(ctx, tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); return rc; }
        (*nfev)++;
    } else {  /* y = (q, v), f = (v, a): v += h/2 a; q += h v; a = a(q); v += h/2 a */
        for (int i = 0; i < nq; i++) { ynew[nq + i] = y[nq + i] + 0.5 * h * fv[nq + i]; ynew[i] = y[i] + h * ynew[nq + i]; }
        if ((rc = f(ctx, tn, ynew, fnew))) { fail_at(dim, fail, tn, ynew); return rc; }
        (*nfev)++;
        for (int i = 0; i < nq; i++) { ynew[nq + i] += 0.5 * h * fnew[nq + i]; fnew[i] = ynew[nq + i]; }
    }
    return 0;
}

/* Fixed steps t_k = t0 + k h, k = 1..N: method 0 classical Runge-Kutta, 1 Stormer-Verlet (kick-drift-kick;
   separable models only: A constant, b independent of the velocities). Outputs tout: a step's state when
   within 1e-7 h of it, else cubic Hermite interpolation between the neighbouring steps.
   Status as lg_dopri5 (4: diverged). */
static int fixed(rhs_fn f, const void *ctx, int nq, int dim, int method, double t0, double h, long N, const double *y0, long nout, const double *tout,
                 volatile double *watch, double *Y, long *counts, double *fail, double *work) {
    double *y = work, *ynew = y + dim, *fv = ynew + dim, *fnew = fv + dim;
    const size_t row = dim * sizeof(double);
    long nfev = 0, o = 0;
    int rc;
    double limit = start_state(dim, y, y0);
    rc = f(ctx, t0, y, fv); nfev++;
    if (rc) { fail_at(dim, fail, t0, y); counts[0] = nfev; return rc; }
    while (o < nout && (tout[o] - t0) / h < 1e-7) { memcpy(Y + o * dim, y, row); o++; }
    for (long k = 1; k <= N && o < nout; k++) {
        const double t = t0 + (k - 1) * h, tn = t0 + k * h;
        if ((rc = fixed_step(f, ctx, nq, dim, method, t, tn, h, work, 1, &nfev, fail))) break;
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
        if ((rc = watched(dim, t0, tn, tn, y, nfev, 0.0, watch, fail))) break;  /* its length is known: no budget */
    }
    counts[0] = nfev; counts[1] = o;
    return rc;
}

/* One fixed step of length h from (t, y), y in the first dim numbers of work (8 dim): the state after it is
   work + dim.  counts[0]: nfev (added to).  Status as lg_dopri5. */
int lg_fixed_step(rhs_fn f, const void *ctx, int nq, int dim, int method, double t, double h, double *work, long *counts, double *fail) {
    int rc = f(ctx, t, work, work + 2 * dim);
    counts[0]++;
    if (rc) { fail_at(dim, fail, t, work); return rc; }
    return fixed_step(f, ctx, nq, dim, method, t, t + h, h, work, 0, counts, fail);
}

int lg_fixed(rhs_fn f, const void *ctx, int nq, int dim, int method, double t0, double h, long N, const double *y0, long nout, const double *tout,
             double *watch, double *Y, long *counts, double *fail) {
    double *work = malloc((size_t)8 * (dim > 0 ? dim : 1) * sizeof(double));
    if (!work) { fail_at(dim, fail, t0, y0); return 5; }
    int rc = fixed(f, ctx, nq, dim, method, t0, h, N, y0, nout, tout, watch, Y, counts, fail, work);
    free(work);
    return rc;
}
"""



@functools.lru_cache(maxsize=1)
def _runtime_source() -> str:
    """The runtime library: the tape interpreter and the stepping loops (model-independent: compiled once per
    compiler and kept in the cache)."""
    return "\n".join([f"/* lagrangian.codegen {CODEGEN_VERSION}: runtime (tape interpreter, stepping loops); do not edit. */",
                      _HEADER, _SOLVE, BAND_SOLVE, _interpreter(), BAND_RUNTIME, _LOOPS, dop853_source(), ENSEMBLE_SOURCE])


# ---------------------------------------------------------------------------
# Build, cache, load
# ---------------------------------------------------------------------------
