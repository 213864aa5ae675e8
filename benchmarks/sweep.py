"""Sweeps: 10,000 random samples of the double pendulum over 10 s, on Dask, against loops of single runs.

Model: the planar double pendulum of ``benchmarks/rhs.py`` (point masses at
the ends of 1 m massless links, absolute angles, g = 9.81), released at rest
from θ = (−π/2 + 0.4, −π/2 − 0.4).  Samples: both masses drawn uniformly in
[0.5, 2] kg (seed 1).  Every run: DOP853 at rtol 1e-9, atol 1e-12 (the
defaults of ``Model.simulate``), both angles kept on 201 times.

- **sweep, 2 workers**: ``lagrangian.sweep.sweep`` on the local default
  cluster (one single-threaded worker process per core: 2 here), all 10,000
  samples; the cluster is started and warmed (workers import lagrangian and
  load the compiled form) by a small sweep first, and its start is reported
  apart;
- **sweep, 1 worker**: the same on a local cluster of one worker
  (``lagrangian.sweep.local_cluster(1)``, the default's settings), for the
  parallel efficiency (2-worker throughput ÷ twice the 1-worker throughput);
- **sweep, serial**: ``client="serial"``, in this process, for information;
- **loop of Model.simulate**: ``model.simulate(10, params=..., ...)`` on the
  first ``--loop`` samples (the same model, the same values), timed in the
  same run: ``speedup_vs_loop`` is the 2-worker throughput over the loop's,
  each the median of ``--repeat`` runs (default 3) interleaved with the
  other's;
- **PyDy**: ``System.integrate`` (``odeint``, rtol 1e-9, atol 1e-12) of
  ``KanesMethod``'s equations with the Cython generator, the constants set
  per sample, on the same samples (the ODE function generated once).

Checks: the sweep's samples equal the loop's to the last bit; the largest
angle difference from PyDy is printed (two integrators at rtol 1e-9 on a
chaotic system: agreement to about 1e-6 over 10 s).

Run: ``.venv/bin/python benchmarks/sweep.py [--samples 10000] [--loop 300] [--repeat 3]``.  The last line is a JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

T_END, POINTS = 10.0, 201
START = [-math.pi / 2 + 0.4, -math.pi / 2 - 0.4]


def ours():
    from rhs import ours_model

    return ours_model(2)


def runs(model):
    init = {"theta_j0": START[0], "theta_j1": START[1]}
    return {"initial": init, "velocity": {k: 0.0 for k in init}, "t_end": T_END, "points": POINTS,
            "outputs": ["theta_j0", "theta_j1"]}


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def loop_simulate(model, masses):
    grid = runs(model)
    out = []
    for m0, m1 in masses:
        res = model.simulate(T_END, initial=grid["initial"], velocity=grid["velocity"], points=POINTS,
                             params={"m_m0": m0, "m_m1": m1})
        out.append([res["theta_j0"], res["theta_j1"]])
    return np.array(out)


def loop_pydy(masses):
    try:
        from pydy.system import System
        from rhs import kane
    except ImportError as exc:
        return None, f"not installed ({exc}); pip install -e '.[bench]'"
    km, q, u, constants = kane(2)
    grid = np.linspace(0.0, T_END, POINTS)
    system = System(km, constants=constants, times=grid,
                    initial_conditions={**dict(zip(q, START)), **{x: 0.0 for x in u}})
    system.generate_ode_function(generator="cython")
    mass = sorted((s for s in constants if s.name.startswith("m")), key=lambda s: s.name)
    order = [system.states.index(qk) for qk in q]
    out = []
    start = time.perf_counter()
    for m0, m1 in masses:
        system.constants = {**constants, mass[0]: m0, mass[1]: m1}
        x = system.integrate(rtol=1e-9, atol=1e-12)
        out.append([x[:, i] for i in order])
    return (np.array(out), time.perf_counter() - start), None


def main() -> None:
    from distributed import Client

    from lagrangian.sweep import Uniform, describe, local_client, local_cluster, sweep

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000)
    ap.add_argument("--loop", type=int, default=300, help="samples timed in the loops of single runs")
    ap.add_argument("--repeat", type=int, default=3, help="runs of the 2-worker sweep and of the loop (medians)")
    args = ap.parse_args()
    model = ours()
    params = {"m_m0": Uniform(0.5, 2.0), "m_m1": Uniform(0.5, 2.0)}
    kw = dict(samples=args.samples, seed=1, **runs(model), progress=False)

    client2, start2 = timed(local_client)
    sweep(model, params, **{**kw, "samples": 64})  # warm: workers import lagrangian, load the compiled form
    ds2, t2 = timed(lambda: sweep(model, params, **kw))
    print(describe(ds2))
    every = np.column_stack([ds2.m_m0.values, ds2.m_m1.values])
    masses = every[: args.loop]
    model.simulate(T_END, **{k: v for k, v in runs(model).items() if k in ("initial", "velocity")})  # warm
    # the 2-worker sweep and the loop, interleaved --repeat times: their medians (a busy moment of the machine
    # slows one run of either, and the ratio of single runs varied from 19 to 25).  Each loop runs samples of
    # its own: the model keeps what it computed for values it has seen, which a loop over new ones pays for.
    repeat = max(1, min(args.repeat, len(every) // args.loop))
    sweeps, loops = [t2], []
    for k in range(repeat):
        out, tl = timed(lambda: loop_simulate(model, every[k * args.loop:(k + 1) * args.loop]))
        if k == 0:
            loop = out
        loops.append(tl)
        if k + 1 < repeat:
            sweeps.append(timed(lambda: sweep(model, params, **kw))[1])
    t2, tl = float(np.median(sweeps)), float(np.median(loops))
    with local_cluster(1) as cluster, \
            Client(cluster, set_as_default=False) as client1:
        sweep(model, params, **{**kw, "samples": 64}, client=client1)
        ds1, t1 = timed(lambda: sweep(model, params, **kw, client=client1))
    dss, ts = timed(lambda: sweep(model, params, **kw, client="serial"))

    swept = np.stack([ds2.theta_j0.values[: args.loop], ds2.theta_j1.values[: args.loop]], axis=1)
    same = bool(np.array_equal(loop, swept))
    pydy, why = loop_pydy(masses)

    rate = {"sweep, 2 workers": args.samples / t2, "sweep, 1 worker": args.samples / t1,
            "sweep, serial (this process)": args.samples / ts, "loop of Model.simulate": args.loop / tl}
    if pydy is not None:
        rate["loop of PyDy System.integrate (Cython)"] = args.loop / pydy[1]
    print(f"\n{args.samples:,} samples of the double pendulum over {T_END:g} s (DOP853, rtol 1e-9), "
          f"{POINTS} output times; local cluster start {start2:.2f} s (once per process)")
    print(f"  the 2-worker sweep and the loop: medians of {repeat} runs each, interleaved (sweep "
          f"{min(sweeps):.2f}–{max(sweeps):.2f} s, loop {min(loops):.2f}–{max(loops):.2f} s)")
    print(f"  {'runs':42} {'samples/s':>10} {'µs/sample':>10}")
    for name, r in rate.items():
        print(f"  {name:42} {r:10.0f} {1e6 / r:10.0f}")
    print(f"  sweep equals the loop of Model.simulate to the last bit: {same}")
    pydy_error = None
    if pydy is not None:
        pydy_error = float(np.max(np.abs(pydy[0] - swept)))
        print(f"  largest angle difference from PyDy over {args.loop} samples: {pydy_error:.2e} rad")
    else:
        print(f"  PyDy: {why}")
    thr2, thr1 = rate["sweep, 2 workers"], rate["sweep, 1 worker"]
    print(json.dumps({"samples": args.samples, "samples_per_s": round(thr2, 1),
                      "speedup_vs_loop": round(thr2 / rate["loop of Model.simulate"], 2),
                      "parallel_efficiency": round(thr2 / (2 * thr1), 3),
                      "speedup_vs_pydy_loop": None if pydy is None else round(thr2 / rate["loop of PyDy System.integrate (Cython)"], 1),
                      "pydy_max_difference": pydy_error, "equal_to_loop": same}))


if __name__ == "__main__":
    main()
