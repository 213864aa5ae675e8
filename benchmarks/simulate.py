"""End to end: simulating the 6-link pendulum for 10 s at rtol 1e-8, ours against PyDy.

Model: the planar 6-link pendulum of ``benchmarks/rhs.py`` (point masses on
massless rods, absolute angles, gravity, m = l = 1, g = 9.81), released at
rest from ``θ_k = −π/2 + 0.4 (−1)^k`` (a zig-zag, ±23° from hanging;
angles from the x axis), output on 101 evenly spaced times.

Each run is a fresh process, timed after its imports (``sympy``,
``scipy.integrate``, and ``lagrangian`` with its plugins, or
``sympy.physics.mechanics`` and PyDy's ``System`` and code generators),
from building the model to the trajectory — derivation, code generation
and compilation, integration — each with a new temporary
``LAGRANGIAN_CACHE_DIR`` holding nothing of the model:

- **ours**: ``Model.simulate(10, method="dopri5_c", rtol=1e-8, atol=1e-8)``
  — Dormand–Prince 5(4) with its stepping loop in C (the energy check
  included), with the default ``compiled="auto"``: the model's tapes run by
  the tape interpreter, nothing compiled for the model.  The cache holds
  only the runtime library (interpreter and stepping loops, the same for
  every model), built beforehand as once per machine.  For information:
  ``ours_first_ever`` — the same with an empty cache (the runtime library
  compiled during the run); ``ours_native`` — ``compiled=True``, the
  model's native library compiled during the run; ``ours_warm`` — the run
  again with that native library in the cache;
- **PyDy**: ``KanesMethod`` → ``System`` → ``generate_ode_function``
  with the ``cython`` and the ``lambdify`` generators →
  ``System.integrate(rtol=1e-8, atol=1e-8)`` (``scipy.integrate.odeint``,
  PyDy's default solver); the faster of the two is PyDy's figure.

Error: the largest difference in any angle over the output times from a
reference computed here by ``solve_ivp(method="DOP853", rtol=1e-13,
atol=1e-13)`` on ``sympy.lambdify`` of Kane's equations (independent of
both).  Median of ``--repeat`` runs.

Run: ``.venv/bin/python benchmarks/simulate.py [--repeat 3]``.  The last line is a JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

N_LINKS, T_END, RTOL, POINTS = 6, 10.0, 1e-8, 101
sys.path.insert(0, str(Path(__file__).resolve().parent))


def initial_angles(n: int) -> list[float]:
    return [-math.pi / 2 + 0.4 * (-1) ** k for k in range(n)]


def child_ours(compiled) -> dict:
    import numpy as np
    import scipy.integrate  # noqa: F401
    import sympy  # noqa: F401

    import lagrangian as lg
    from rhs import ours_model

    lg.default_registry()
    grid = np.linspace(0.0, T_END, POINTS)
    start = time.perf_counter()
    model = ours_model(N_LINKS)
    init = {f"theta_j{k}": a for k, a in enumerate(initial_angles(N_LINKS))}
    res = model.simulate(T_END, initial=init, velocity={k: 0.0 for k in init}, t_eval=grid, method="dopri5_c",
                         rtol=RTOL, atol=RTOL, compiled=compiled)
    seconds = time.perf_counter() - start
    return {"seconds": seconds, "q": [res[f"theta_j{k}"].tolist() for k in range(N_LINKS)], "nfev": res.nfev,
            "notes": [n for n in res.notes if "compiled" in n]}


def child_runtime() -> dict:
    from lagrangian import codegen

    start = time.perf_counter()
    path = codegen.runtime()
    return {"seconds": time.perf_counter() - start, "path": str(path)}


def child_pydy(generator: str) -> dict:
    import numpy as np
    import scipy.integrate  # noqa: F401
    import sympy.physics.mechanics  # noqa: F401
    from pydy.system import System
    import pydy.codegen.ode_function_generators  # noqa: F401

    from rhs import kane

    grid = np.linspace(0.0, T_END, POINTS)
    start = time.perf_counter()
    km, q, u, constants = kane(N_LINKS)
    system = System(km, constants=constants, times=grid,
                    initial_conditions={**dict(zip(q, initial_angles(N_LINKS))), **{x: 0.0 for x in u}})
    system.generate_ode_function(generator=generator)
    x = system.integrate(rtol=RTOL, atol=RTOL)
    seconds = time.perf_counter() - start
    order = [system.states.index(qk) for qk in q]
    return {"seconds": seconds, "q": [x[:, i].tolist() for i in order]}


def reference():
    import numpy as np
    from scipy.integrate import solve_ivp

    from rhs import lambdify_rhs

    rhs = lambdify_rhs(N_LINKS)
    y0 = np.array(initial_angles(N_LINKS) + [0.0] * N_LINKS)
    grid = np.linspace(0.0, T_END, POINTS)
    sol = solve_ivp(lambda t, y: rhs(y, t), (0.0, T_END), y0, method="DOP853", t_eval=grid, rtol=1e-13, atol=1e-13)
    return sol.y[:N_LINKS]


def run(which: str, cache: str) -> dict:
    env = {**os.environ, "LAGRANGIAN_CACHE_DIR": cache}
    proc = subprocess.run([sys.executable, __file__, "--child", which], capture_output=True, text=True, check=False, env=env)
    if proc.returncode:
        return {"error": (proc.stderr.strip().splitlines() or ["failed"])[-1]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child = {"ours": lambda: child_ours("auto"), "ours_native": lambda: child_ours(True), "runtime": child_runtime}
        print(json.dumps(child[args.child]() if args.child in child else child_pydy(args.child.split("_")[1])))
        return
    import numpy as np

    ref = reference()
    rows, why = {}, {}
    try:
        import pydy  # noqa: F401
        import Cython  # noqa: F401
        peers = ["pydy_cython", "pydy_lambdify"]
    except ImportError as exc:
        peers = []
        why["pydy"] = f"not installed ({exc}); pip install -e '.[bench]'"
    setups = {  # what the cache holds before each timed run: (child, what to run first in the same cache)
        "ours": ("ours", ["runtime"]),
        "ours_first_ever": ("ours", []),
        "ours_native": ("ours_native", ["runtime"]),
        "ours_warm": ("ours", ["ours_native"]),
        **{p: (p, []) for p in peers},
    }
    for which, (child, before) in setups.items():
        runs = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as cache:
                for step in before:
                    run(step, cache)
                runs.append(run(child, cache))
        good = [r for r in runs if "seconds" in r]
        if not good:
            why[which] = runs[0]["error"]
            continue
        error = float(np.max(np.abs(np.array(good[0]["q"]) - ref)))
        rows[which] = {"seconds": statistics.median(r["seconds"] for r in good), "error": error,
                       "nfev": good[0].get("nfev"), "notes": good[0].get("notes", [])}
    print(f"planar {N_LINKS}-link pendulum, {T_END:g} s, rtol = atol = {RTOL:g}, {POINTS} output times; fresh process "
          f"per run (median of {args.repeat}), nothing of the model cached; error: max |Δθ| against DOP853 at rtol 1e-13")
    print(f"{'who':<16} {'end-to-end s':>13} {'max error':>10} {'time / ours':>12}")
    ours = rows.get("ours")
    for which, row in rows.items():
        ratio = row["seconds"] / ours["seconds"] if ours else float("nan")
        print(f"{which:<16} {row['seconds']:>13.3f} {row['error']:>10.2e} {ratio:>12.1f}")
    for which, reason in why.items():
        print(f"{which}: no figure — {reason}")
    print("ours: the default (compiled='auto': the tape interpreter; the runtime library built beforehand, once per "
          "machine); ours_first_ever: an empty cache (the runtime library compiled in the run); ours_native: "
          "compiled=True (the model's C compiled in the run); ours_warm: compiled='auto' with that library cached")
    for which in ("ours", "ours_native", "ours_warm"):
        if which in rows:
            print(f"{which}: {'; '.join(rows[which]['notes'])}")
    best = min((rows[p] for p in peers if p in rows), key=lambda r: r["seconds"], default=None)
    if best is not None and ours:
        print(f"PyDy's best ({min((p for p in peers if p in rows), key=lambda p: rows[p]['seconds'])}) takes "
              f"{best['seconds'] / ours['seconds']:.1f}× our time, error {best['error']:.1e} against our {ours['error']:.1e}")
    print(json.dumps({"ours_s": None if not ours else round(ours["seconds"], 4),
                      "pydy_s": None if best is None else round(best["seconds"], 4),
                      "ours_error": None if not ours else float(f"{ours['error']:.3e}"),
                      "pydy_error": None if best is None else float(f"{best['error']:.3e}")}))


if __name__ == "__main__":
    main()
