"""Electrostatic pull-in: a plate on a spring, attracted by a voltage across a gap.
================================================================================

A voltage source charges, through a resistor, a parallel-plate capacitor
whose plate (mass m, on a spring k, with a damper c) moves towards the fixed
electrode: C(x) = εA/(gap − x), V_el = q²/2C(x) in the Lagrangian.  At a DC
voltage V the plate rests where k x = εA V² / (2 (gap − x)²); that stable
equilibrium exists only up to the pull-in voltage

    V_pi = sqrt(8 k gap³ / (27 εA)),   reached at x = gap/3,

beyond which the plate snaps onto the electrode.  The script tabulates the
equilibria against V (lagrangian.plugins.transducers.electrostatic_equilibria),
compares the pull-in point with the closed form, reports that no stable
equilibrium exists past it, and simulates a step below pull-in (the plate
settles) and one above (the simulation stops with a GapClosedError when the
gap closes).  The numbers are in units where gap = εA = k = m = 1: the
problem is scale-free (V_pi / sqrt(k gap³/εA) = sqrt(8/27) always).

The step below pull-in is cross-checked in ngspice: the model maps through
the force–voltage analogy to one deck, the plate's mass, spring and damper
an inductor, a capacitor and a resistor in series, the variable capacitor a
two-port of behavioural sources (q = C(x)·v, force q²/2εA); every state
quantity is compared with the simulation on ngspice's time points
(lagrangian.compare.compare_with_ngspice).

Run: .venv/bin/python examples/electrostatic_pullin.py [--out electrostatic_pullin.png]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.compare import compare_with_ngspice
from lagrangian.plugins.transducers import GapClosedError, PullInError, electrostatic_equilibria, simulate_checked
from lagrangian.spice import NgspiceMissingError

EPS_A, GAP = 1.0, 1.0  # ε·A, rest gap
K, M, C = 1.0, 1.0, 1.0  # spring, plate mass, damper
R = 0.1  # source resistance


def actuator() -> lg.Model:
    m = lg.Model("electrostatic actuator")
    m.add("voltage_source", "V", ("n1", "0"), E=sp.Symbol("V"))  # a DC step from t = 0, value per run
    m.add("resistor", "R", ("n1", "n2"), R=R)
    m.add("variable_capacitor", "Cx", ("n2", "0", "plate"), eps_A=EPS_A, gap=GAP)
    m.add("mass", "m", "plate", m=M)
    m.add("spring", "k", ("ground", "plate"), k=K)
    m.add("damper", "c", ("ground", "plate"), c=C)
    return m


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="electrostatic_pullin.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    model = actuator()
    print(model.describe())

    v_pi_exact = np.sqrt(8 * K * GAP**3 / (27 * EPS_A))
    report = electrostatic_equilibria(model, "Cx", 0.0)
    print(f"\npull-in voltage:      computed {report.pull_in_voltage:.10f}, closed form sqrt(8 k gap³/27 εA) = {v_pi_exact:.10f}")
    print(f"pull-in displacement: computed {report.pull_in_displacement:.10f}, closed form gap/3 = {GAP / 3:.10f}")

    print(f"\n{'V/V_pi':>8} {'V':>10}  equilibria (x/gap)")
    curve = []
    for ratio in (0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 0.99, 0.999, 1.01, 1.1, 1.5):
        v = ratio * v_pi_exact
        eq = electrostatic_equilibria(model, "Cx", v)
        listed = ", ".join(f"{e.x / GAP:.6f} ({'stable' if e.stable else 'unstable'})" for e in eq.equilibria) or "none"
        print(f"{ratio:8.3f} {v:10.6f}  {listed}")
        curve.append((v, eq))
    past = electrostatic_equilibria(model, "Cx", 1.1 * v_pi_exact)
    print(f"\npast pull-in: {past}")
    try:
        past.position
    except PullInError as exc:
        print(f"  asking for its rest position raises {type(exc).__name__}")

    below, above = 0.9 * v_pi_exact, 1.05 * v_pi_exact
    runs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # from rest, uncharged
        res = simulate_checked(model, 60, params={"V": below}, points=801)
        x_eq = electrostatic_equilibria(model, "Cx", below).position
        print(f"\nstep to V = 0.9 V_pi: the plate settles at x = {res['x_plate'][-1]:.9f}; stable equilibrium {x_eq:.9f}")
        runs["0.9 V_pi: settles"] = res
        try:
            simulate_checked(model, 40, params={"V": above}, points=801)
            raise SystemExit("the simulation past pull-in should have stopped at contact")
        except GapClosedError as exc:
            print(f"step to V = 1.05 V_pi: {type(exc).__name__}: {exc}")
            contact = exc.time
        runs["1.05 V_pi: pull-in"] = model.simulate(0.999 * contact, params={"V": above}, points=801)

    try:  # the same step below pull-in in ngspice
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", lg.InitialConditionWarning)
            cmp = compare_with_ngspice(model, 60, analogy="force-voltage", params={"V": below}, step=0.01, max_step=1e-3)
    except NgspiceMissingError as exc:
        print(f"\nngspice cross-check skipped: {exc}")
    else:
        x_spice = GAP * cmp.spice["v(T_Cx.x)"][-1]  # the two-port's internal node holds x/gap
        print(f"\nngspice cross-check of the step to 0.9 V_pi:\n{cmp.table()}")
        print(f"ngspice vs simulation: worst {cmp.worst_rel:.2e} of peak; in ngspice the plate rests at x = {x_spice:.9f} "
              f"(stable equilibrium {x_eq:.9f})")

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.5), constrained_layout=True)
    x = np.linspace(0, GAP, 400, endpoint=False)
    v_of_x = np.sqrt(2 * K * x * (GAP - x) ** 2 / EPS_A)  # the voltage holding the plate at x, by hand
    left.plot(v_of_x[x <= GAP / 3], x[x <= GAP / 3], color="C0", label="stable (closed form)")
    left.plot(v_of_x[x >= GAP / 3], x[x >= GAP / 3], "--", color="C0", label="unstable (closed form)")
    for v, eq in curve:
        for e in eq.equilibria:
            left.plot(v, e.x, "o" if e.stable else "x", color="C1", ms=5)
    left.plot([report.pull_in_voltage], [report.pull_in_displacement], "*", color="C3", ms=14, label="pull-in (computed)")
    left.axvline(v_pi_exact, color="C3", ls=":", lw=1, label=f"V_pi = {v_pi_exact:.4f}")
    left.set_xlabel("DC voltage V")
    left.set_ylabel("plate displacement x (gap = 1)")
    left.set_title("Equilibria of the plate")
    left.grid(True, alpha=0.3)
    left.legend(fontsize=8)
    for label, r in runs.items():
        right.plot(r.t, r["x_plate"], label=label)
    right.axhline(GAP, color="k", lw=1, label="electrode (x = gap)")
    right.axhline(GAP / 3, color="C3", ls=":", lw=1, label="pull-in displacement gap/3")
    right.plot([contact], [GAP], "*", color="C3", ms=12)
    right.set_xlabel("t")
    right.set_ylabel("x_plate")
    right.set_title("Voltage steps below and above pull-in")
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
