"""Scenes: the full model against the scene's minimal model, end to end.

Six scenes; the first three reduce (their question needs part of the model), the last three rightly decline:

* ``shaker``: a shaker table (a prescribed motion) carries 10 identical
  two-mass pendulum-spring assemblies in the plane (40 coordinates,
  nonlinear); the question is one assembly's lower mass.
* ``bench``: a motor test bench: a prescribed rotation drives 30 two-stage
  shaft–rotor branches with drag (60 coordinates, linear); the question is
  one branch's output rotor.
* ``lab``: twenty spring pendulums (a bob on a spring with a rest length,
  under gravity) hung side by side in the plane (40 coordinates,
  nonlinear); the question is one bob.
* ``kepler``: a planet on a turning arm (θ ignorable); the question is the
  radius over some 60 orbits.
* ``top``: a symmetric top on three revolute joints (precession, nutation,
  spin; 3 coordinates, two of them ignorable); the question is the nutation
  angle over a long run.
* ``loudspeaker``: a moving-coil loudspeaker driven by a sine (coil circuit
  and cone, linear); the question is the cone displacement.

Each variant runs in a fresh process (so derivation, code generation and
integration are all timed, with no warm caches): the full model simulated
with DOP853 at rtol = tol, and the scene (plan + run + outputs).  Times are
given with the import (the wall time of the process's work) and after it
(what the scene changes: the CPU time of the work, which a busy machine
disturbs less than wall time; the median of the runs, full and scene
interleaved so that a machine that slows down slows both alike, with the
spread printed: a scene that declines every simplification costs what the
full model costs within a few milliseconds, and the least of a few runs of
either is decided by one lucky run, ±7 % here).  The import is that of
the libraries either path needs (SymPy, SciPy, networkx, mpmath: the
package itself imports them on first use) and of ``lagrangian.scene``.  The scene's report (the whole model's sizes among
it) is read after the timing: a scene pruned by its component graph derives
the whole model only for it.  Scenes weigh a Routhian reduction against
integrating the part as it is (``Scene(reduce="auto")``) and report why.  The error
columns are the largest difference between the minimal model's outputs and
the full model's, and each one's against a tight reference (the full model
at rtol 1e-12).  Prints a table; the last line is
``{"scenes": N, "min_speedup": …, "min_speedup_after_import": …, "max_error": …, "scenes_reducing": …,
"min_speedup_reducing": …, "min_speedup_declining": …}`` (the last two after the import); writes a PNG.

Run: .venv/bin/python benchmarks/scenes.py [--repeat 5] [--out benchmarks/scenes.png]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

TOL = 1e-10
SCENES = ("shaker", "bench", "lab", "kepler", "top", "loudspeaker")


def build(name: str):
    import sympy as sp

    import lagrangian as lg

    if name == "shaker":
        m = lg.Model("shaker table", dim=2)
        m.add("prescribed_motion", "table", "deck", position=sp.Matrix([sp.sin(4 * lg.t) / 20, 0]))
        initial, velocity = {}, {}
        for k in range(10):
            m.add("mass", f"upper{k}", f"u{k}", m=1.0)
            m.add("mass", f"lower{k}", f"w{k}", m=0.5)
            m.add("spring", f"hang{k}", ("deck", f"u{k}"), k=60.0 + k, rest_length=0.5)
            m.add("spring", f"link{k}", (f"u{k}", f"w{k}"), k=40.0, rest_length=0.4)
            m.add("damper", f"drag{k}", ("deck", f"u{k}"), c=0.05)
            initial.update({f"x_u{k}": 0.1, f"y_u{k}": -0.5, f"x_w{k}": 0.15, f"y_w{k}": -0.9})
            velocity.update({f"x_u{k}": 0.0, f"y_u{k}": 0.0, f"x_w{k}": 0.0, f"y_w{k}": 0.0})
        m.add("gravity", "g", g=9.81)
        return m, ["x_w3", "y_w3"], 20.0, initial, velocity
    if name == "bench":
        m = lg.Model("motor test bench")
        m.add("prescribed_rotation", "motor", "shaft", angle=2 * lg.t + sp.sin(5 * lg.t) / 10)
        initial, velocity = {}, {}
        for k in range(30):
            m.add("torsion_spring", f"input{k}", ("shaft", f"r{k}"), k=40.0 + 3 * k)
            m.add("inertia", f"rotor{k}", f"r{k}", J=0.02 + 0.001 * k)
            m.add("rotary_damper", f"drag{k}", ("shaft", f"r{k}"), c=0.05)
            m.add("torsion_spring", f"output{k}", (f"r{k}", f"s{k}"), k=25.0)
            m.add("inertia", f"load{k}", f"s{k}", J=0.05)
            m.add("rotary_damper", f"brake{k}", (f"s{k}", "ground"), c=0.02)
            for node in (f"r{k}", f"s{k}"):
                initial[f"theta_{node}"], velocity[f"theta_{node}"] = 0.0, 0.0
        return m, ["theta_s5"], 20.0, initial, velocity
    if name == "lab":
        m = lg.Model("spring pendulums", dim=2)
        initial, velocity = {}, {}
        for k in range(20):
            m.add("mass", f"bob{k}", f"b{k}", m=0.2 + 0.05 * k)
            m.add("spring", f"coil{k}", (f"h{k}", f"b{k}"), k=30.0, rest_length=0.4)
            m.add("prescribed_motion", f"hook{k}", f"h{k}", position=(0.5 * k, 0.0))
            initial.update({f"x_b{k}": 0.5 * k + 0.2, f"y_b{k}": -0.5})
            velocity.update({f"x_b{k}": 0.0, f"y_b{k}": 0.0})
        m.add("gravity", "g", g=9.81)
        return m, ["x_b3", "y_b3"], 20.0, initial, velocity
    if name == "top":
        m = lg.Model("symmetric top", dim=3)
        m.add("link", "frame", "frame")
        m.add("revolute", "precession", ("ground", "frame"), axis=(0, 0, 1))
        m.add("link", "gimbal", "gimbal")
        m.add("revolute", "nutation", ("frame", "gimbal"), axis=(1, 0, 0))
        m.add("body", "rotor", "rotor", m=1.0, inertia=(0.03, 0.03, 0.05), com=(0, 0, 0.3))
        m.add("revolute", "spin", ("gimbal", "rotor"), axis=(0, 0, 1))
        m.add("gravity", "g", g=9.81)
        initial = {"theta_precession": 0.0, "theta_nutation": 0.5, "theta_spin": 0.0}
        velocity = {"theta_precession": 1.0, "theta_nutation": 0.0, "theta_spin": 40.0}
        return m, ["theta_nutation"], 100.0, initial, velocity
    if name == "kepler":
        m = lg.Model("kepler", dim=2)
        m.add("link", "arm", "arm")
        m.add("revolute", "orbit", ("ground", "arm"), absolute=True)
        m.add("link", "bead", "bead")
        m.add("prismatic", "radius", ("arm", "bead"))
        m.add("mass", "planet", "bead", m=1.0)
        m.add("central_force", "sun", ("ground", "bead"), k=1.0)
        initial = {"theta_orbit": 0.0, "s_radius": 1.0}
        velocity = {"theta_orbit": 0.75, "s_radius": 0.3}
        return m, ["s_radius"], 400.0, initial, velocity
    if name == "loudspeaker":
        m = lg.Model("loudspeaker")
        m.add("voltage_source", "V1", ("n1", "0"), E=sp.sin(300 * lg.t))
        m.add("resistor", "Re", ("n1", "n2"), R=6)
        m.add("inductor", "Le", ("n2", "n3"), L=0.5e-3)
        m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=7)
        m.add("mass", "Mms", "cone", m=0.02)
        m.add("spring", "Kms", ("ground", "cone"), k=2000)
        m.add("damper", "Rms", ("ground", "cone"), c=1.5)
        zero = {"q_Le": 0.0, "x_cone": 0.0}
        return m, ["x_cone"], 0.5, zero, dict(zero)
    raise SystemExit(f"unknown scene {name!r}")


def one(name: str, which: str, tol: float) -> dict:
    """One timed run in this (fresh) process; returns its outputs, wall time and the CPU time of the work."""
    start = time.perf_counter()
    import mpmath  # noqa: F401 - what either path imports when it first needs it: part of the import (the package
    import networkx  # noqa: F401 - imports SymPy, networkx and mpmath on first use: lagrangian.base.deferred)
    import scipy.integrate  # noqa: F401
    import scipy.linalg  # noqa: F401
    import scipy.sparse  # noqa: F401
    import sympy  # noqa: F401

    from lagrangian.scene import Scene

    imported, cpu = time.perf_counter(), time.process_time()
    model, outputs, span, initial, velocity = build(name)
    grid = np.linspace(0, span, 2001)
    if which == "scene":
        scene = Scene(model, outputs, span, tol=tol, initial=initial, velocity=velocity, t_eval=grid)
        res = scene.run()
        values = {o: res[o].tolist() for o in outputs}
    else:
        res = model.simulate(span, initial=initial, velocity=velocity, t_eval=grid, rtol=tol, atol=tol * 1e-3)
        values = {o: res[o].tolist() for o in outputs}
    end, cpu = time.perf_counter(), time.process_time() - cpu
    info = {}
    if which == "scene":  # the report, after the timing: the whole model's sizes are derived when read
        plan = scene.plan
        info = {"before": dict(plan.before), "after": plan.after, "parts": [p.method for p in plan.parts],
                "eliminated": [c for p in plan.parts for c in p.eliminated]}
    return {"wall": end - start, "work": end - imported, "cpu": cpu, "values": values, "info": info}


def fresh(name: str, which: str, tol: float) -> dict:
    proc = subprocess.run([sys.executable, __file__, "--one", name, which, str(tol)], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{name}/{which} failed:\n{proc.stderr}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5,
                        help="fresh-process runs per variant (median wall and CPU time; the spread is printed)")
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent / "scenes.png"), help="chart (PNG)")
    parser.add_argument("--one", nargs=3, metavar=("SCENE", "WHICH", "TOL"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        name, which, tol = args.one
        print(json.dumps(one(name, which, float(tol))))
        return
    from scale import bytecode

    bytecode()  # each fresh process reads the package compiled, as an installed one is
    rows = []
    for name in SCENES:
        runs = {"full": [], "scene": []}
        for _ in range(args.repeat):  # interleaved: a machine that slows down slows both alike
            for w in runs:
                runs[w].append(fresh(name, w, TOL))
        ref = fresh(name, "full", 1e-12)
        wall = {w: statistics.median(r["wall"] for r in rs) for w, rs in runs.items()}
        work = {w: statistics.median(r["cpu"] for r in rs) for w, rs in runs.items()}
        full, minimal = runs["full"][0]["values"], runs["scene"][0]["values"]
        gap = max(float(np.max(np.abs(np.array(minimal[o]) - np.array(full[o])))) for o in full)
        err_full = max(float(np.max(np.abs(np.array(full[o]) - np.array(ref["values"][o])))) for o in full)
        err_min = max(float(np.max(np.abs(np.array(minimal[o]) - np.array(ref["values"][o])))) for o in full)
        info = runs["scene"][0]["info"]
        rows.append({"scene": name, "full_s": wall["full"], "minimal_s": wall["scene"], "speedup": wall["full"] / wall["scene"],
                     "work_speedup": work["full"] / work["scene"], "full_work_s": work["full"], "minimal_work_s": work["scene"],
                     "difference": gap, "full_error": err_full, "minimal_error": err_min, **info})
        spread = {w: (min(r["cpu"] for r in rs), max(r["cpu"] for r in rs)) for w, rs in runs.items()}
        print(f"{name}: CPU after import, full {spread['full'][0]:.3f}–{spread['full'][1]:.3f} s, minimal "
              f"{spread['scene'][0]:.3f}–{spread['scene'][1]:.3f} s over {args.repeat} runs each")
        print(f"{name}: full {wall['full']:.3f} s, minimal {wall['scene']:.3f} s; coordinates {info['before']['coordinates']} → "
              f"{info['after']['coordinates']}, operations {info['before']['operations']} → {info['after']['operations']}; "
              f"parts {info['parts']}, eliminated {info['eliminated']}", flush=True)
    print()
    print("| scene | full s | minimal s | speed-up | after import (CPU): full s | minimal s | speed-up | coords before → after | ops before → after | max |minimal − full| | full err | minimal err |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['full_s']:.3f} | {r['minimal_s']:.3f} | {r['speedup']:.2f} | "
              f"{r['full_work_s']:.3f} | {r['minimal_work_s']:.3f} | {r['work_speedup']:.2f} | "
              f"{r['before']['coordinates']} → {r['after']['coordinates']} | {r['before']['operations']} → {r['after']['operations']} | "
              f"{r['difference']:.2e} | {r['full_error']:.2e} | {r['minimal_error']:.2e} |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    x = np.arange(len(rows))
    left.bar(x - 0.2, [r["full_s"] for r in rows], 0.4, label="full model")
    left.bar(x + 0.2, [r["minimal_s"] for r in rows], 0.4, label="scene's minimal model")
    left.set_xticks(x, [r["scene"] for r in rows])
    left.set_yscale("log")
    left.set_ylabel("wall time, fresh process [s]")
    left.legend()
    right.bar(x - 0.2, [max(r["full_error"], 1e-17) for r in rows], 0.4, label="full vs reference")
    right.bar(x + 0.2, [max(r["minimal_error"], 1e-17) for r in rows], 0.4, label="minimal vs reference")
    right.set_xticks(x, [r["scene"] for r in rows])
    right.set_yscale("log")
    right.set_ylabel(f"max error of the outputs (rtol {TOL:g})")
    right.legend()
    fig.savefig(args.out, dpi=110)
    print(f"chart: {args.out}")
    reducing = [r for r in rows if r["after"]["coordinates"] < r["before"]["coordinates"]]
    declining = [r for r in rows if r not in reducing]
    print(json.dumps({"scenes": len(rows), "min_speedup": round(min(r["speedup"] for r in rows), 3),
                      "min_speedup_after_import": round(min(r["work_speedup"] for r in rows), 3),
                      "max_error": max(r["difference"] for r in rows),
                      "scenes_reducing": len(reducing),
                      "min_speedup_reducing": round(min((r["work_speedup"] for r in reducing), default=0.0), 3),
                      "max_error_reducing": max((r["difference"] for r in reducing), default=0.0),
                      "min_speedup_declining": round(min((r["work_speedup"] for r in declining), default=0.0), 3)}))


if __name__ == "__main__":
    main()
