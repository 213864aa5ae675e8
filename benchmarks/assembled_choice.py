"""Where the runs assembled in numbers pay: a large model of lumped components on the assembled path
(:mod:`lagrangian.numerics.assembled`) against the symbolic path, size by size — what
``lagrangian.numerics.assembled.ASSEMBLED_MIN`` is chosen from.

Models: a Fermi–Pasta–Ulam–Tsingou β chain of n unit masses between two walls (cubic springs, from its mode n/10,
as ``benchmarks/scale.py`` runs it), and a damped chain of n masses driven at its end (linear springs).  For each size
and path, in a fresh process with an empty cache, CPU time (``time.process_time``), best of ``--repeat`` processes:

- ``first_s``: the first ``simulate(1.0)`` of a fresh model with default settings (assembly or derivation, tapes,
  the run): what a user waits for;
- ``long_s``: a second run of the same model over ``--long`` seconds (nothing built again), and ``per_eval_us`` that
  divided by its evaluations: what a long run costs once built (the symbolic path steps in C, on the tape
  interpreter; the assembled one in SciPy's DOP853, which costs more per step).

Both paths' states at the end of the first run are compared (``agreement``, largest difference relative to the
largest state; must be below 1e-7: both take DOP853's steps at rtol 1e-9).  ``threshold``: the fewest coordinates
from which the assembled path is no slower for a 1 s run (``first_s``) nor for both runs together
(``first_s + long_s``) at that and every larger size measured, for both models.

Prints a table and, as its last line, a JSON object.

Run: ``.venv/bin/python benchmarks/assembled_choice.py [--sizes 50,100,200,400,1000] [--repeat 3] [--long 20]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
import warnings

import numpy as np

AGREEMENT = 1e-7


def build(kind: str, n: int):
    import sympy as sp

    import lagrangian as lg
    from lagrangian import models

    if kind == "fput":
        m = models.spring_chain(n, m=1.0, k=100.0, beta=1e6)
        m.add("spring", f"k{n}", (f"p{n - 1}", "ground"), k=100.0, beta=1e6)
        mode = max(n // 10, 1)
        start = {f"x_p{i}": 0.05 * np.sin(np.pi * mode * (i + 1) / (n + 1)) for i in range(n)}
    else:
        m = models.spring_chain(n, m=[0.3 + 0.01 * (i % 7) for i in range(n)], k=[40.0 + i % 5 for i in range(n)],
                                c=0.02, force=0.5 * sp.sin(3 * lg.t))
        start = {f"x_p{i}": 0.0 for i in range(n)} | {"x_p0": 0.01}
    return m, start


def child(kind: str, n: int, path: str, long: float) -> dict:
    from lagrangian.numerics import assembled

    assembled.ASSEMBLED_MIN = 1 if path == "assembled" else 10**9
    m, start = build(kind, n)
    velocity = {name: 0.0 for name in start}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        began = time.process_time()
        res = m.simulate(1.0, initial=start, velocity=velocity, points=11)
        first = time.process_time() - began
        began = time.process_time()
        again = m.simulate(long, initial=start, velocity=velocity, points=11)
        second = time.process_time() - began
    assert ("assembled in numbers" in res.notes[0]) == (path == "assembled"), res.notes
    return {"first_s": first, "long_s": second, "per_eval_us": 1e6 * second / max(again.nfev, 1),
            "end": [float(res[name][-1]) for name in m.coordinate_names]}


def run_child(kind: str, n: int, path: str, long: float) -> dict:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, LAGRANGIAN_CACHE_DIR=cache)
        out = subprocess.run([sys.executable, __file__, "--child", kind, str(n), path, str(long)], env=env,
                             capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="50,100,200,400,1000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--long", type=float, default=20.0)
    ap.add_argument("--child", nargs=4)
    args = ap.parse_args()
    if args.child:
        kind, n, path, long = args.child
        print(json.dumps(child(kind, int(n), path, float(long))))
        return
    sizes = [int(s) for s in args.sizes.split(",")]
    rows, worst = [], 0.0
    print(f"{'model':6} {'n':>6} {'path':10} {'first_s':>9} {'long_s':>9} {'per_eval_us':>12}")
    for kind in ("fput", "linear"):
        for n in sizes:
            got = {}
            for path in ("assembled", "symbolic"):
                runs = [run_child(kind, n, path, args.long) for _ in range(args.repeat)]
                got[path] = {key: min(r[key] for r in runs) for key in ("first_s", "long_s", "per_eval_us")}
                got[path]["end"] = np.array(runs[0]["end"])
                print(f"{kind:6} {n:>6} {path:10} {got[path]['first_s']:9.3f} {got[path]['long_s']:9.3f} "
                      f"{got[path]['per_eval_us']:12.1f}", flush=True)
            a, s = got["assembled"]["end"], got["symbolic"]["end"]
            worst = max(worst, float(np.max(np.abs(a - s)) / max(float(np.max(np.abs(s))), 1e-300)))
            rows.append({"model": kind, "n": n,
                         **{f"{p}_{k}": got[p][k] for p in got for k in ("first_s", "long_s", "per_eval_us")}})
    if worst > AGREEMENT:
        raise SystemExit(f"the two paths disagree: {worst:.3g} relative")
    pays = {n: all(r["assembled_first_s"] <= r["symbolic_first_s"]
                   and r["assembled_first_s"] + r["assembled_long_s"] <= r["symbolic_first_s"] + r["symbolic_long_s"]
                   for r in rows if r["n"] == n) for n in sizes}
    threshold = next((n for i, n in enumerate(sizes) if all(pays[m] for m in sizes[i:])), None)
    print(json.dumps({"rows": rows, "agreement": worst, "threshold": threshold}))


if __name__ == "__main__":
    main()
