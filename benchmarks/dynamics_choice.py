"""Where the recursive dynamics (the articulated-body algorithm) pay: closed-form equations against the recursion on
the same mechanisms, size by size — what ``lagrangian.plugins.multibody.RECURSIVE_FROM`` is chosen from.

Models (``benchmarks/multibody.py``'s): planar chains of n rods on revolute joints (n joint coordinates), spatial
chains of n bodies on spherical joints (3n).  For each size and form (``Model(dynamics="closed")`` and
``Model(dynamics="recursive")``), in this process, CPU time (``time.process_time``), best of ``--repeat``:

- ``build_s``: a fresh model's derivation (``model.eq``) and its tapes (``codegen.programs``), what a first run of
  the default path costs;
- ``tape_us``: one evaluation of the right-hand side on the tape interpreter, called in a loop in C;
- ``native_us``: the same on the model's native library (its compilation not counted).

Before timing, both forms' right-hand sides are compared at 5 random states (largest relative difference,
``agreement``; must be below 1e-10).  ``threshold``: the fewest joint coordinates from which the recursion is no
slower on the tape and natively, at every larger size measured, and builds no slower (within 5 %: a build is a
tenth of a second here, and its time varies by that much from run to run).

Prints a table and, as its last line, a JSON object.

Run: ``.venv/bin/python benchmarks/dynamics_choice.py [--planar 2,3,4,5,6,8,10,12,16] [--spatial 1,2,3,4] [--repeat 3]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import multibody  # noqa: E402  (the models and the C loop: benchmarks/multibody.py)
import spatial  # noqa: E402

AGREEMENT = 1e-10


def model(kind: str, n: int, dynamics: str):
    from lagrangian import models

    if kind == "planar":
        return models.pendulum_chain(n, m=multibody.LINK_M, length=multibody.LINK_L, g=multibody.G, dynamics=dynamics)
    return spatial.ours(n, dynamics=dynamics)


def one(kind: str, n: int, dynamics: str, repeat: int, states: np.ndarray, workdir: str) -> dict:
    from lagrangian import codegen

    builds, m = [], None
    for _ in range(repeat):
        began = time.process_time()
        m = model(kind, n, dynamics)
        numeric = m.numeric()
        codegen.programs(numeric)
        builds.append(time.process_time() - began)
    assert (m.eq.recursion is not None) == (dynamics == "recursive")
    tape, _ = codegen.compile_model(m.numeric(), "tape")
    native, _ = codegen.compile_model(m.numeric(), "native")
    calls = max(2000, int(2e6 / (n * n)))
    out = {"build_s": min(builds)}
    for name, compiled in (("tape_us", tape), ("native_us", native)):
        loop = multibody.CLoop(compiled, workdir)
        out[name] = min(loop(states, calls) for _ in range(repeat))
    out["rhs"] = native
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--planar", default="2,3,4,5,6,8,10,12,16")
    parser.add_argument("--spatial", default="1,2,3,4")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    import lagrangian as lg

    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    rows = []
    workdir = tempfile.mkdtemp(prefix="lg-choice-")
    for kind, sizes in (("planar", args.planar), ("spatial", args.spatial)):
        for n in [int(x) for x in sizes.split(",") if x]:
            dof = n if kind == "planar" else 3 * n
            states = multibody.random_states(kind, n, 64, seed=11)
            print(f"[{kind} {n}] ...", file=sys.stderr, flush=True)
            closed = one(kind, n, "closed", args.repeat, states, workdir)
            rec = one(kind, n, "recursive", args.repeat, states, workdir)
            worst = 0.0
            for y in states[:5]:
                a, b = rec["rhs"].rhs(0.0, y)[dof:], closed["rhs"].rhs(0.0, y)[dof:]
                worst = max(worst, float(np.max(np.abs(a - b)) / np.max(np.abs(b))))
            if not worst < AGREEMENT:
                raise SystemExit(f"{kind} {n}: the two forms disagree by {worst:.2e}")
            rows.append({"kind": kind, "n": n, "dof": dof, "agreement": worst,
                         **{f"closed_{k}": v for k, v in closed.items() if k != "rhs"},
                         **{f"recursive_{k}": v for k, v in rec.items() if k != "rhs"}})
    print(f"{'model':>12} {'dof':>4} | {'build s closed/rec':>20} | {'tape µs closed/rec':>20} | "
          f"{'native µs closed/rec':>22} | agreement")
    for r in rows:
        print(f"{r['kind'] + ' ' + str(r['n']):>12} {r['dof']:>4} | {r['closed_build_s']:9.3f} {r['recursive_build_s']:9.3f}"
              f"  | {r['closed_tape_us']:9.3f} {r['recursive_tape_us']:9.3f}  | {r['closed_native_us']:10.3f} "
              f"{r['recursive_native_us']:10.3f}  | {r['agreement']:.1e}")

    def pays(r) -> bool:
        return (r["recursive_tape_us"] <= r["closed_tape_us"] and r["recursive_native_us"] <= r["closed_native_us"]
                and r["recursive_build_s"] <= 1.05 * r["closed_build_s"])

    by_dof = sorted(rows, key=lambda r: r["dof"])
    threshold = next((r["dof"] for k, r in enumerate(by_dof) if all(pays(s) for s in by_dof[k:])), None)
    print(json.dumps({"threshold": threshold, "rows": rows}))


if __name__ == "__main__":
    main()
