"""A DC motor spinning up a flywheel after a voltage step, against the closed form.
================================================================================

One Lagrangian holds the armature circuit (step source V, resistance R,
inductance La), the motor (constant K: L ∋ K·θ·q̇, torque K·i, back-emf K·θ̇)
and the flywheel (inertia J on a bearing with viscous friction b):

    La di/dt + R i + K ω = V,        J dω/dt + b ω = K i.

Starting at rest, ω(t) = ω_ss (1 + (s₂ e^{s₁t} − s₁ e^{s₂t}) / (s₁ − s₂)),
with s₁, s₂ the roots of La J s² + (R J + La b) s + (R b + K²) = 0 and the
steady speed ω_ss = K V / (R b + K²); with La → 0 this is the first-order
spin-up ω_ss (1 − e^{−t/τ}) of mechanical time constant τ = J R / (R b + K²).
Prints both time constants and the steady speed, the largest difference
between simulation and closed form, and writes a chart.  The spin-up is
cross-checked in ngspice: through the torque–voltage analogy the flywheel
and bearing become an inductor and a resistor, the motor a gyrator (two
current-controlled voltage sources), all in one deck compared state by state
with the simulation (lagrangian.compare.compare_with_ngspice).

Run: .venv/bin/python examples/dc_motor.py [--out dc_motor.png]
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import lagrangian as lg
from lagrangian.compare import compare_with_ngspice
from lagrangian.spice import NgspiceMissingError

V = 12.0  # V, step at t = 0
R, LA = 1.0, 0.5e-3  # Ω, H: armature resistance and inductance
K = 0.05  # N m/A = V s/rad
J, B = 1e-4, 1e-5  # kg m², N m s/rad: flywheel inertia, bearing friction


def motor() -> lg.Model:
    m = lg.Model("dc-motor")
    m.add("voltage_source", "V", ("n1", "0"), E=V)
    m.add("resistor", "R", ("n1", "n2"), R=R)
    m.add("inductor", "La", ("n2", "n3"), L=LA)
    m.add("dc_motor", "M", ("n3", "0", "shaft"), K=K)
    m.add("inertia", "J", "shaft", J=J)
    m.add("rotary_damper", "b", ("ground", "shaft"), c=B)
    return m


def closed_form(t: np.ndarray) -> tuple[np.ndarray, complex, complex]:
    """ω(t) from rest (i = ω = 0 at t = 0), derived by hand; also the two poles."""
    s1, s2 = np.roots([LA * J, R * J + LA * B, R * B + K**2])
    w_ss = K * V / (R * B + K**2)
    w = w_ss * (1 + (s2 * np.exp(s1 * t) - s1 * np.exp(s2 * t)) / (s1 - s2))
    return np.real(w), s1, s2


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="dc_motor.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    model = motor()
    print(model.describe())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # from rest: q = θ = 0, i = ω = 0
        res = model.simulate(0.3, points=1201, method="LSODA", rtol=1e-10, atol=1e-12)
    omega = res.velocity("theta_shaft")
    current = res.velocity(model.coordinate_names[0])
    exact, s1, s2 = closed_form(res.t)

    w_ss = K * V / (R * B + K**2)
    tau_m = J * R / (R * B + K**2)
    tau = -1 / max(np.real(s1), np.real(s2))
    print(f"\nsteady speed ω_ss = K V / (R b + K²) = {w_ss:.6f} rad/s ({w_ss * 60 / (2 * np.pi):.2f} rpm)")
    print(f"simulated ω(0.3 s) = {omega[-1]:.6f} rad/s")
    print(f"poles s₁, s₂ = {s1:.6g}, {s2:.6g} 1/s")
    print(f"time constant (slow pole) τ = {tau * 1e3:.6f} ms")
    print(f"  mechanical τ_m = J R / (R b + K²) = {tau_m * 1e3:.6f} ms (La → 0); electrical La/R = {LA / R * 1e3:.6f} ms")
    print(f"stall current V/R = {V / R:.3f} A, peak simulated current {current.max():.4f} A")
    print(f"max |ω − closed form| = {np.max(np.abs(omega - exact)):.3e} rad/s ({np.max(np.abs(omega - exact)) / w_ss:.2e} of ω_ss)")
    i63 = np.searchsorted(omega, (1 - np.exp(-1)) * w_ss)
    print(f"ω reaches 63.2 % of ω_ss at t = {res.t[i63] * 1e3:.2f} ms (grid of {res.t[1] * 1e3:.2f} ms)")

    try:
        cmp = compare_with_ngspice(model, 0.3, analogy="torque-voltage", step=1e-4, max_step=5e-6, method="exact")
    except NgspiceMissingError as exc:
        print(f"\nngspice cross-check skipped: {exc}")
    else:
        print(f"\nngspice cross-check of the spin-up:\n{cmp.table()}")
        print(f"ngspice vs simulation: worst {cmp.worst_rel:.2e} of peak")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    top.plot(res.t * 1e3, omega, lw=2.5, label="simulated ω(t)")
    top.plot(res.t * 1e3, exact, "--", color="k", lw=1, label="closed form")
    top.axhline(w_ss, color="C2", ls=":", label=f"ω_ss = {w_ss:.1f} rad/s")
    top.axvline(tau * 1e3, color="C3", ls=":", label=f"τ = {tau * 1e3:.2f} ms")
    top.set_ylabel("ω [rad/s]")
    top.set_title(f"DC motor spinning up a flywheel after a {V:g} V step")
    top.grid(True, alpha=0.3)
    top.legend(loc="lower right")
    bottom.plot(res.t * 1e3, current, color="C1", label="armature current i(t)")
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
