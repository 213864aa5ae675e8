"""A solenoid plunger after a voltage step, against its closed-form rest position and ngspice.
===========================================================================================

One Lagrangian holds the coil circuit (step source V, resistance R), the
solenoid (inductance L(x) = L0/(1 + x/x0): T = ½ L(x) q̇² in the charge
formulation, V = λ²/2L(x) in the flux formulation) and the plunger (mass m
on a spring k with a damper c).  The current pulls the plunger towards
smaller x, closing the air gap, with F = ½ i² L'(x) = −L0 i² / (2 x0 (1 + x/x0)²).
At rest the current is V/R whatever x is, and the plunger sits where

    k x (1 + x/x0)² = −L0 (V/R)² / (2 x0),

solved here with Brent's method.  A stable rest position exists only while
L0 i² / (2 x0) < (4/27) k x0 (the solenoid's pull-in, at x = −x0/3).

The script simulates the step, compares the rest position with the closed
form, and runs the same model in ngspice through both analogies: through
force–voltage (the model in the charge formulation) the plunger's mass,
spring and damper become an inductor, a capacitor and a resistor in one
mesh; through force–current (the flux formulation) a capacitor, an inductor
and a resistor on one node; either way the solenoid becomes a two-port of
behavioural sources (λ = ∫v on an internal node, i = λ/L(x), force
−λ²/(2 L0 x0)).  Each state quantity is compared with the simulation on
ngspice's time points (lagrangian.compare.compare_with_ngspice).

Run: .venv/bin/python examples/solenoid.py [--out solenoid.png]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.optimize import brentq

import lagrangian as lg
from lagrangian.compare import compare_with_ngspice
from lagrangian.spice import NgspiceMissingError

V, R = 5.0, 50.0  # V, Ω: the step and the coil's resistance (L0/R = 1 ms)
L0, X0 = 0.05, 2e-3  # H, m: inductance with the gap closed, travel that halves it
M, K, C = 0.01, 1000.0, 3.0  # kg, N/m, N s/m: plunger, return spring (50 Hz), damper (ζ ≈ 0.47)
T_END = 0.2  # s


def plunger(formulation: str = "charge") -> lg.Model:
    m = lg.Model("solenoid plunger", formulation=formulation)
    m.add("voltage_source", "V", ("n1", "0"), E=V)
    m.add("resistor", "R", ("n1", "n2"), R=R)
    m.add("solenoid", "S", ("n2", "0", "plunger"), L0=L0, x0=X0)  # current n2 → 0 pulls the plunger to −x
    m.add("mass", "m", "plunger", m=M)
    m.add("spring", "k", ("ground", "plunger"), k=K)
    m.add("damper", "c", ("ground", "plunger"), c=C)
    return m


def rest_position() -> float:
    """The stable root of k x (1 + x/x0)² = −L0 (V/R)² / (2 x0), between the pull-in point −x0/3 and 0."""
    i = V / R
    return brentq(lambda x: K * x + L0 * i**2 / (2 * X0 * (1 + x / X0) ** 2), -X0 / 3, 0.0, xtol=1e-18, rtol=1e-15)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="solenoid.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    model = plunger()
    print(model.describe())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # from rest, no current
        res = model.simulate(T_END, points=2001, method="LSODA", rtol=1e-12, atol=1e-16)
    x = res["x_plunger"]
    current = res.velocity(model.coordinate_names[0])  # the loop charge through R and the coil
    x_eq = rest_position()
    i_pi = np.sqrt(8 * K * X0**2 / (27 * L0))
    print(f"\nsteady current V/R = {V / R:.6f} A (pull-in current sqrt(8 k x0² / 27 L0) = {i_pi:.6f} A)")
    print(f"rest position: closed form {x_eq * 1e6:.6f} µm, simulated {x[-1] * 1e6:.6f} µm "
          f"(relative difference {abs(x[-1] / x_eq - 1):.2e}); largest excursion {x.min() * 1e6:.3f} µm")

    runs = {}
    for formulation, analogy in (("charge", "force-voltage"), ("flux", "force-current")):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", lg.InitialConditionWarning)
                cmp = compare_with_ngspice(plunger(formulation), T_END, analogy=analogy, step=1e-4, max_step=1e-5,
                                           method="LSODA", rtol=1e-12, atol=1e-16)
        except NgspiceMissingError as exc:
            print(f"\nngspice cross-check skipped: {exc}")
            break
        x_spice = X0 * cmp.spice["v(T_S.x)"]  # the two-port's internal node holds x/x0
        runs[analogy] = (cmp.time, x_spice)
        print(f"\nngspice, {formulation} formulation through the {analogy} analogy:\n{cmp.table()}")
        print(f"ngspice vs simulation ({analogy}): worst {cmp.worst_rel:.2e} of peak; rest position in ngspice "
              f"{x_spice[-1] * 1e6:.6f} µm (relative difference to the closed form {abs(x_spice[-1] / x_eq - 1):.2e})")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    top.plot(res.t * 1e3, x * 1e6, lw=2.5, label="lagrangian")
    for (analogy, (t, xs)), style in zip(runs.items(), ("--", ":")):
        top.plot(t * 1e3, xs * 1e6, style, lw=1.2, label=f"ngspice ({analogy})")
    top.axhline(x_eq * 1e6, color="k", lw=0.8, label=f"closed-form rest position {x_eq * 1e6:.2f} µm")
    top.set_ylabel("x [µm]")
    top.set_title(f"Solenoid plunger after a {V:g} V step")
    top.grid(True, alpha=0.3)
    top.legend(fontsize=8)
    bottom.plot(res.t * 1e3, current, color="C1", label="coil current i(t)")
    bottom.axhline(V / R, color="k", lw=0.8, ls=":", label="V/R")
    bottom.set_ylabel("i [A]")
    bottom.set_xlabel("t [ms]")
    bottom.grid(True, alpha=0.3)
    bottom.legend()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
