"""Side by side with ngspice: agreement, speed and accuracy on the issue's comparison cases.

For each case (a mass–spring–damper through both analogies, a two-mass
chain, a loudspeaker, an imported 5th-order LC ladder filter):

- agreement: our solution against ngspice's on ngspice's own time points,
  as the largest error relative to each signal's peak (ngspice's step
  capped at ``max_step``);
- accuracy and speed on the linear path: a tight reference (DOP853 at
  rtol 1e-13) on a uniform output grid; ngspice's error against it (at its
  own points) and its run time; ours — the exact solution by matrix
  exponentials on the same output grid — likewise.

Prints a table and, as its last line, a JSON object.  Run: ``make benchmark``.
"""

from __future__ import annotations

import json
import statistics
import time
import warnings

import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.analogy import map_model
from lagrangian.compare import compare_with_ngspice
from lagrangian.netlist import read_netlist
from lagrangian.spice import netlist, run_transient

LADDER = """5th-order Butterworth LC ladder low-pass, 1 rad/s cut-off, 1 ohm terminations
V1 in 0 SIN(0 1 0.15 0 0 0)
Rs in n1 1
C1 n1 0 0.618034
L2 n1 n2 1.618034
C3 n2 0 2
L4 n2 n3 1.618034
C5 n3 0 0.618034
Rl n3 0 1
.tran 0.01 30 0 2.5e-4 uic
.end
"""


def msd():
    m = lg.Model("mass-spring-damper")
    m.add("mass", "m", "p", m=1.0)
    m.add("spring", "k", ("ground", "p"), k=4.0)
    m.add("damper", "c", ("ground", "p"), c=0.4)
    m.add("force", "F", "p", F=sp.sin(1.5 * lg.t))
    return m, {"x_p": 0.1}, {"x_p": 0.0}


def chain():
    m = lg.Model("two-mass chain")
    m.add("mass", "m1", "a", m=1.0)
    m.add("mass", "m2", "b", m=2.0)
    m.add("spring", "k1", ("ground", "a"), k=4.0)
    m.add("spring", "k2", ("a", "b"), k=3.0)
    m.add("damper", "c2", ("a", "b"), c=0.3)
    m.add("force", "F", "b", F=sp.cos(lg.t))
    return m, {"x_a": 0.1, "x_b": -0.2}, {"x_a": 0.3, "x_b": 0.0}


def loudspeaker():
    m = lg.Model("loudspeaker")
    m.add("voltage_source", "V", ("n1", "0"), E=sp.sin(2 * sp.pi * 40 * lg.t))
    m.add("resistor", "Re", ("n1", "n2"), R=6.0)
    m.add("inductor", "Le", ("n2", "n3"), L=0.5e-3)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=7.0)
    m.add("mass", "mc", "cone", m=0.02)
    m.add("spring", "ks", ("ground", "cone"), k=2000.0)
    m.add("damper", "cs", ("ground", "cone"), c=1.5)
    return m, {}, {}


def ladder():
    net = read_netlist(LADDER, name="LC ladder (imported)")
    return net.model, net.initial, net.velocity


# (label, build, analogy, t_end, output step, ngspice step cap)
CASES = [
    ("mass-spring-damper, force-voltage", msd, "force-voltage", 20.0, 0.01, 2.5e-4),
    ("mass-spring-damper, force-current", msd, "force-current", 20.0, 0.01, 2.5e-4),
    ("two-mass chain, force-current", chain, "force-current", 20.0, 0.01, 2.5e-4),
    ("loudspeaker, force-voltage", loudspeaker, "force-voltage", 0.1, 1e-4, 2e-6),
    ("LC ladder (imported netlist)", ladder, None, 30.0, 0.01, 2.5e-4),
]


def best_of(n, fn):
    times = []
    for _ in range(n):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return min(times), out


def main() -> None:
    warnings.simplefilter("ignore", lg.InitialConditionWarning)
    import scipy.integrate  # noqa: F401  (imported once, outside every timing)
    rows = []
    print(f"{'case':36} {'agree':>9} | {'ngspice ms':>10} {'ngspice err':>11} | {'ours ms':>8} {'ours err':>9} {'set-up ms':>9}")
    for label, build, analogy, t_end, step, cap in CASES:
        model, initial, velocity = build()
        agreement = compare_with_ngspice(
            model, t_end, analogy=analogy, initial=initial, velocity=velocity, step=step, max_step=cap, method="exact"
        )
        # the circuit ngspice runs, its state quantities, and their meaning in the model
        if analogy:
            mapped = map_model(model, analogy)
            circuit, (ci, cv) = mapped.model, mapped.initial(initial, velocity)
            meaning = mapped.to_source
        else:
            circuit, ci, cv, meaning = model, initial, velocity, lambda e: e
        net = netlist(circuit, initial=ci, velocity=cv, t_end=t_end, step=step, max_step=cap)
        runs = [run_transient(net) for _ in range(3)]
        run = min(runs, key=lambda r: r.wall)  # ngspice's own run time, load and parse excluded
        grid = np.arange(0.0, t_end + step / 2, step)
        reference = model.simulate(t_end, initial=initial, velocity=velocity, t_eval=np.union1d(grid, run.time),
                                   method="DOP853", rtol=1e-13, atol=1e-15)
        ref_at = {label_: reference.quantity(meaning(expr)) for label_, expr in net.quantities.items()}
        on_grid = np.isin(reference.t, grid)
        on_spice = np.isin(reference.t, run.time)
        fresh, _, _ = build()
        start = time.perf_counter()  # first use on a new model: derivation, state space, code generation, solve
        fresh.simulate(t_end, initial=initial, velocity=velocity, t_eval=grid, method="exact")
        setup_s = time.perf_counter() - start
        ours_s, ours = best_of(5, lambda: model.simulate(t_end, initial=initial, velocity=velocity, t_eval=grid, method="exact"))
        spice_err = ours_err = 0.0
        for label_, expr in net.quantities.items():
            peak = np.max(np.abs(ref_at[label_]))
            spice_err = max(spice_err, np.max(np.abs(run.quantities[label_] - ref_at[label_][on_spice])) / peak)
            ours_err = max(ours_err, np.max(np.abs(ours.quantity(meaning(expr)) - ref_at[label_][on_grid])) / peak)
        rows.append(dict(case=label, agree=agreement.worst_rel, spice_s=run.wall, spice_err=spice_err,
                         ours_s=ours_s, ours_err=ours_err, setup_s=setup_s))
        print(f"{label:36} {agreement.worst_rel:9.2e} | {run.wall * 1e3:10.1f} {spice_err:11.2e} | "
              f"{ours_s * 1e3:8.2f} {ours_err:9.2e} {setup_s * 1e3:9.0f}")
    print("(errors relative to each quantity's peak; 'ours err' is bounded below by the reference's own ~1e-12;")
    print(" times: ngspice's run without parsing, ours the exact solve on the output grid, best of several;")
    print(" set-up: our first use of a new model, derivation and code generation included)")
    summary = {
        "worst_rel_error": max(r["agree"] for r in rows),
        "cases": len(rows),
        "linear_speedup_vs_ngspice": statistics.median(r["spice_s"] / r["ours_s"] for r in rows),
        "linear_error_ratio_vs_ngspice": statistics.median(r["spice_err"] / max(r["ours_err"], 1e-300) for r in rows),
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
