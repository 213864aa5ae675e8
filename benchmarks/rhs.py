"""Evaluating the right-hand side: our compiled C against sympy.lambdify and PyDy's code generators.

Model: the planar n-link pendulum (n = 3, 6, 10) — point masses on massless
rods, absolute angles, gravity, m = l = 1, g = 9.81 — built with our
multibody plugin (as ``benchmarks/derivation.py`` builds it) and, for the
peers, with ``sympy.physics.mechanics.KanesMethod``.  State
``(q_1..q_n, u_1..u_n)``, ``u = q̇``.

Per-call time (µs, the median of repeated batches of calls, each at a
random state, after a warm-up):

- **ours**: ``lagrangian.codegen`` — the tapes of ``A`` and ``b`` (every
  common subexpression once), the solve ``A u = b`` by LU in C, called
  through ctypes (``CompiledModel.rhs``), both ways the tapes run: the
  model's ``native`` library (tapes printed as C, compiled) and the shared
  ``tape`` interpreter (nothing compiled per model).  The stepping loops
  ``dopri5_c``/``rk4_c`` call the same C functions without Python: the
  ``native C`` and ``tape C`` columns, each called in a loop in C, beside
  ``hand C``, a C function of the same pendulum written by hand —
  closed-form ``M`` and ``f``, the same LU — called the same way;
- **lambdify**: ``sympy.lambdify(cse=True)`` of Kane's ``M`` and forcing,
  then ``numpy.linalg.solve``;
- **PyDy** ``System.generate_ode_function`` with the ``lambdify`` and the
  ``cython`` generators (``pydy`` and ``Cython`` installed; ``null`` and the
  reason otherwise).

Code generation time (s; median of fresh processes, after the imports and
the derivation): ours ``compile_model`` native (tapes, C source, ``cc -O3``)
for a model not in the cache (a temporary ``LAGRANGIAN_CACHE_DIR``) and on
the tape (recording the tapes), both with the runtime library (the tape
interpreter and the stepping loops, model-independent) built beforehand, as
``make setup`` builds it once per machine; its own build is timed apart
(``runtime_once_s``).  Against PyDy's cython generator (Cython + C compile
of the model's module).  All right-hand
sides are checked against each other at a random state.

Run: ``.venv/bin/python benchmarks/rhs.py [--sizes 3,6,10] [--repeat 3]``.  The last line is a JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import timeit

G = 9.81


def ours_model(n: int):
    import lagrangian as lg

    model = lg.Model(f"{n}-link pendulum", dim=2)
    parent = "ground"
    for k in range(n):
        model.add("link", f"L{k}", f"L{k}", points={"end": (1, 0)})
        model.add("revolute", f"j{k}", (parent, f"L{k}"), absolute=True, **({"parent_point": (1, 0)} if k else {}))
        model.add("mass", f"m{k}", f"L{k}.end", m=1)
        parent = f"L{k}"
    model.add("gravity", "g", g=G)
    return model


def kane(n: int):
    """KanesMethod for the same pendulum, symbolic m_k, l_k, g (as PyDy users write it): benchmarks/derivation.py's."""
    from derivation import kane as kanes_method, parameters

    km, _, _ = kanes_method(n, shared=False)
    m, l, g = parameters(n, shared=False)
    constants = {**{s: 1.0 for s in m + l}, g: G}
    return km, list(km.q), list(km.u), constants


def pydy_system(n: int):
    from pydy.system import System

    km, q, u, constants = kane(n)
    return System(km, constants=constants), constants


HAND_C = r"""
/* The n-link pendulum written by hand: m = l = 1, absolute angles from the x axis, gravity -y.
   M_ij = (n - max(i,j)) cos(q_i - q_j),  f_i = -sum_j (n - max(i,j)) sin(q_i - q_j) u_j^2 - g (n - i) cos q_i;
   solved by the same LU with partial pivoting as the generated code. */
#include <math.h>
#include <float.h>
#define N %(n)d
int lg_rhs(const void *ctx, double t, const double *y, double *dy) {
    double s[N], c[N], A[N * N], b[N];
    const double *q = y, *u = y + N;
    for (int i = 0; i < N; i++) { s[i] = sin(q[i]); c[i] = cos(q[i]); }
    for (int i = 0; i < N; i++) {
        double f = -%(g)r * (N - i) * c[i];
        for (int j = 0; j < N; j++) {
            int w = N - (i > j ? i : j);
            A[i * N + j] = w * (c[i] * c[j] + s[i] * s[j]);
            f -= w * (s[i] * c[j] - c[i] * s[j]) * u[j] * u[j];
        }
        b[i] = f;
    }
    for (int k = 0; k < N; k++) {
        int p = k; double best = fabs(A[k * N + k]);
        for (int i = k + 1; i < N; i++) if (fabs(A[i * N + k]) > best) { best = fabs(A[i * N + k]); p = i; }
        if (!(best > 0)) return 1;
        if (p != k) {
            for (int j = k; j < N; j++) { double x = A[k * N + j]; A[k * N + j] = A[p * N + j]; A[p * N + j] = x; }
            double x = b[k]; b[k] = b[p]; b[p] = x;
        }
        double inv = 1.0 / A[k * N + k];
        for (int i = k + 1; i < N; i++) {
            double f = A[i * N + k] * inv;
            for (int j = k + 1; j < N; j++) A[i * N + j] -= f * A[k * N + j];
            b[i] -= f * b[k];
        }
    }
    for (int k = N - 1; k >= 0; k--) {
        double x = b[k];
        for (int j = k + 1; j < N; j++) x -= A[k * N + j] * b[j];
        b[k] = x / A[k * N + k];
    }
    for (int i = 0; i < N; i++) { dy[i] = u[i]; dy[N + i] = b[i]; }
    return 0;
}
"""

DRIVER_C = r"""
typedef int (*rhs_fn)(const void *ctx, double t, const double *y, double *dy);
int lg_rhs(const void *ctx, double t, const double *y, double *dy);
/* calls evaluations of f at the states Y (nstates rows of dim), the last result in out */
int bench_fn(rhs_fn f, const void *ctx, long calls, const double *Y, long nstates, long dim, double *out) {
    int rc = 0;
    for (long k = 0; k < calls; k++) rc |= f(ctx, 0.0, Y + (k %% nstates) * dim, out);
    return rc;
}
int bench(long calls, const double *Y, long nstates, long dim, double *out) {
    return bench_fn(lg_rhs, 0, calls, Y, nstates, dim, out);
}
"""
TAPE_DRIVER_C = r"""
int lg_rhs(const void *ctx, double t, const double *y, double *dy) { return 1; }  /* unused: the tape is passed in */
"""


def c_loop_us(sources: list[str], states, calls: int, workdir: str, name: str, tape=None) -> tuple[float, list]:
    """Per-call µs of ``lg_rhs`` from ``sources`` called in a C loop (``cc`` with ``codegen.FLAGS``), and its value at ``states[0]``;
    with ``tape`` (a ``CompiledModel`` of kind ``"tape"``), of the tape interpreter's right-hand side instead."""
    import ctypes

    import numpy as np

    from lagrangian import codegen

    paths = []
    for k, text in enumerate([DRIVER_C % {}, *sources]):
        path = os.path.join(workdir, f"{name}{k}.c")
        with open(path, "w") as fh:
            fh.write(text)
        paths.append(path)
    lib = os.path.join(workdir, f"{name}.so")
    subprocess.run([codegen.compiler(), *codegen.FLAGS, "-o", lib, *paths, "-lm"], check=True)
    dll = ctypes.CDLL(lib)
    Y = np.ascontiguousarray(states)
    out = np.zeros(Y.shape[1])
    args = (ctypes.c_long(calls), Y.ctypes.data_as(ctypes.c_void_p), ctypes.c_long(Y.shape[0]), ctypes.c_long(Y.shape[1]),
            out.ctypes.data_as(ctypes.c_void_p))
    bench = dll.bench if tape is None else (lambda *a: dll.bench_fn(ctypes.c_void_p(tape._rhs_ptr), ctypes.c_void_p(tape._ctx), *a))
    runs = []
    for _ in range(5):
        start = time.perf_counter()
        bench(*args)
        runs.append((time.perf_counter() - start) / calls * 1e6)
    bench(ctypes.c_long(1), *args[1:])
    return statistics.median(runs), out.tolist()


def lambdify_rhs(n: int):
    """sympy.lambdify(cse=True) of Kane's M and forcing (numbers substituted) + numpy.linalg.solve."""
    import numpy as np
    import sympy as sp

    km, q, u, constants = kane(n)
    qs, us = sp.symbols(f"q:{n}"), sp.symbols(f"u:{n}")
    subs = {**dict(zip(q, qs)), **dict(zip(u, us)), **constants}
    M = km.mass_matrix.xreplace(subs)
    F = km.forcing.xreplace(subs)
    fn = sp.lambdify([qs, us], [M, F], modules="numpy", cse=True)

    def rhs(y, t):
        Mv, Fv = fn(y[:n], y[n:])
        return np.concatenate([y[n:], np.linalg.solve(np.asarray(Mv, dtype=float), np.asarray(Fv, dtype=float).ravel())])

    return rhs


# -- children ---------------------------------------------------------------------------------------


def child_codegen(method: str, n: int) -> dict:
    """Time code generation alone, in this fresh process (imports and derivation excluded)."""
    import sympy.physics.mechanics  # noqa: F401

    import lagrangian as lg

    lg.default_registry()
    if method.startswith("ours"):
        from lagrangian import codegen

        numeric = ours_model(n).numeric()
        with tempfile.TemporaryDirectory() as cache:
            codegen.set_cache_dir(cache)
            began = time.perf_counter()
            codegen.runtime()  # built once per machine (make setup), not per model
            runtime = time.perf_counter() - began
            start = time.perf_counter()
            compiled, note = codegen.compile_model(numeric, "tape" if method == "ours_tape" else "native")
            seconds = time.perf_counter() - start
        if compiled is None:
            raise SystemExit(note)
        return {"seconds": seconds, "runtime": runtime}
    if method == "lambdify":
        km, q, u, constants = kane(n)
        start = time.perf_counter()
        lambdify_rhs(n)
        return {"seconds": time.perf_counter() - start}  # includes a second (cheap) Kane derivation
    import pydy.codegen.ode_function_generators  # noqa: F401

    system, _ = pydy_system(n)
    start = time.perf_counter()
    system.generate_ode_function(generator=method.split("_")[1])
    return {"seconds": time.perf_counter() - start}


def child_calls(n: int, calls: int) -> dict:
    """Per-call times (µs) of every right-hand side at random states, and their agreement."""
    import numpy as np

    import lagrangian as lg
    from lagrangian import codegen

    rng = np.random.default_rng(1)
    states = [np.concatenate([rng.uniform(-np.pi, np.pi, n), rng.uniform(-2, 2, n)]) for _ in range(64)]
    funcs, out, why = {}, {}, {}
    with tempfile.TemporaryDirectory() as cache:
        codegen.set_cache_dir(cache)
        model = ours_model(n)
        compiled, note = codegen.compile_model(model.numeric())
        if compiled is None:
            raise SystemExit(note)
        funcs["ours"] = lambda y, t: compiled.rhs(t, y)
        tape, note = codegen.compile_model(model.numeric(), "tape")
        if tape is None:
            raise SystemExit(note)
        funcs["ours_tape"] = lambda y, t: tape.rhs(t, y)
        # the generated C function and a hand-written one, each called in a loop in C
        Y = np.array(states)
        with open(compiled.path.with_suffix(".c")) as fh:
            generated = fh.read()
        out["ours_c"], ours_first = c_loop_us([generated], Y, 200000, cache, "ours")
        out["hand_c"], hand_first = c_loop_us([HAND_C % {"n": n, "g": G}], Y, 200000, cache, "hand")
        out["ours_tape_c"], _ = c_loop_us([TAPE_DRIVER_C], Y, 200000, cache, "tape", tape=tape)
        hand_diff = float(np.max(np.abs(np.array(ours_first) - np.array(hand_first))))
    funcs["lambdify"] = lambdify_rhs(n)
    try:
        import pydy  # noqa: F401
        import pydy.codegen.ode_function_generators  # noqa: F401
    except ImportError as exc:
        why["pydy"] = f"pydy does not import ({exc}); pip install -e '.[bench]'"
    else:
        for gen in ("lambdify", "cython"):
            try:
                system, constants = pydy_system(n)
                f = system.generate_ode_function(generator=gen)
                p = np.array([constants[s] for s in system.constants_symbols])
                funcs[f"pydy_{gen}"] = (lambda f, p: lambda y, t: f(y, t, p))(f, p)
            except Exception as exc:  # a peer that does not build is reported, not fatal
                why[f"pydy_{gen}"] = f"{type(exc).__name__}: {str(exc)[:200]}"
    ref = [funcs["lambdify"](y, 0.0) for y in states]
    diffs = {}
    for name, f in funcs.items():
        diffs[name] = max(float(np.max(np.abs(f(y, 0.0) - r))) for y, r in zip(states, ref))
        for y in states[:8]:
            f(y, 0.0)  # warm-up
        batches = []
        for _ in range(15):
            start = time.perf_counter()
            for i in range(calls):
                f(states[i & 63], 0.0)
            batches.append((time.perf_counter() - start) / calls * 1e6)
        out[name] = statistics.median(batches)
    diffs["hand_c"] = hand_diff
    return {"us": out, "diff": diffs, "why": why}


def run(args: list[str]) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--child", *args], capture_output=True, text=True, check=False)
    if proc.returncode:
        return {"error": (proc.stderr.strip().splitlines() or ["failed"])[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def fmt(x, spec=".2f") -> str:
    return "n/a" if x is None else format(x, spec)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="3,6,10")
    ap.add_argument("--repeat", type=int, default=3, help="fresh processes per code-generation timing (median)")
    ap.add_argument("--calls", type=int, default=2000, help="calls per timed batch")
    ap.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        kind, *rest = args.child
        result = child_calls(int(rest[0]), args.calls) if kind == "calls" else child_codegen(rest[0], int(rest[1]))
        print(json.dumps(result))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    print("planar n-link pendulum, m = l = 1, g = 9.81; right-hand side per call (µs, median of batches at random "
          "states) and code generation (s, median of fresh processes, cold cache)")
    print(f"{'n':>3} {'native':>7} {'tape':>6} {'native C':>9} {'tape C':>7} {'hand C':>7} {'lambdify':>9} {'PyDy lamb':>10} "
          f"{'PyDy cython':>12} {'cython/ours':>12} | {'gen native':>11} {'gen tape':>9} {'gen cython':>11} {'cython/native':>14} | {'max diff':>9}")
    last = None
    notes = set()
    for n in sizes:
        calls = run(["calls", str(n)])
        if "error" in calls:
            raise SystemExit(f"n={n}: {calls['error']}")
        us, why = calls["us"], calls["why"]
        notes.update(f"{k}: {v}" for k, v in why.items())
        gen = {}
        for method in ("ours", "ours_tape", "pydy_cython"):
            if not method.startswith("ours") and method not in us:
                gen[method] = None
                continue
            runs = [run(["codegen", method, str(n)]) for _ in range(args.repeat)]
            good = [r["seconds"] for r in runs if "seconds" in r]
            gen[method] = statistics.median(good) if good else None
            if method == "ours" and good:
                gen["runtime"] = statistics.median(r["runtime"] for r in runs if "runtime" in r)
            if not good:
                notes.add(f"{method} code generation: {runs[0]['error']}")
        cy = us.get("pydy_cython")
        print(f"{n:>3} {us['ours']:>7.2f} {us['ours_tape']:>6.2f} {us['ours_c']:>9.3f} {us['ours_tape_c']:>7.3f} {us['hand_c']:>7.3f} "
              f"{us['lambdify']:>9.2f} {fmt(us.get('pydy_lambdify')):>10} {fmt(cy):>12} "
              f"{fmt(cy / max(us['ours'], us['ours_tape']) if cy else None, '.1f'):>12} | {gen['ours']:>11.3f} "
              f"{gen['ours_tape']:>9.4f} {fmt(gen['pydy_cython'], '.3f'):>11} "
              f"{fmt(gen['pydy_cython'] / gen['ours'] if gen['pydy_cython'] else None, '.1f'):>14} | {max(calls['diff'].values()):>9.1e}")
        last = {"n": n, "ours_us": round(us["ours"], 3), "lambdify_us": round(us["lambdify"], 3),
                "pydy_cython_us": None if cy is None else round(cy, 3), "ours_codegen_s": round(gen["ours"], 4),
                "pydy_cython_codegen_s": None if gen["pydy_cython"] is None else round(gen["pydy_cython"], 4),
                "ours_tape_us": round(us["ours_tape"], 3), "ours_tape_codegen_s": round(gen["ours_tape"], 5),
                "runtime_once_s": round(gen["runtime"], 3),
                "cython_codegen_over_native": None if gen["pydy_cython"] is None else round(gen["pydy_cython"] / gen["ours"], 2)}
    for note in sorted(notes):
        print("note:", note)
    print("native, tape: CompiledModel.rhs called from Python (ctypes), as solve_ivp or a Python loop calls it, for the "
          "model's native library and for the tape interpreter; native C, tape C, hand C: the generated lg_rhs, the tape "
          "interpreter, and a hand-written C function of the same system (same LU), called in a loop in C, as the "
          "compiled stepping loops (dopri5_c, rk4_c, verlet_c) call them; gen native: tapes + C source + cc -O3 of a "
          "model not in the cache; gen tape: recording the tapes; both with the runtime library already built, as "
          f"make setup builds it once per machine (its build: {gen.get('runtime', float('nan')):.2f} s)")
    print(json.dumps(last))


if __name__ == "__main__":
    main()
