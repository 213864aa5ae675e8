"""A loudspeaker: its electrical impedance peaks at the mechanical resonance.
==========================================================================

One Lagrangian holds the voice-coil circuit (source E, resistance Re,
inductance Le), the moving coil (force factor Bl: L ∋ Bl·x·q̇) and the cone
(mass m on a suspension of stiffness k with damping c).  For each drive
frequency the script simulates the response to E = sin(ωt) until the
transient has died out, fits the steady-state current, and compares the
impedance E/I with the closed form

    Z(jω) = Re + jωLe + (Bl)² / (c + jωm + k/(jω)),

whose peak Re + (Bl)²/c sits at the mechanical resonance f_s = √(k/m)/2π.
Writes a chart of ``|Z|`` and its phase against frequency.  The drive at f_s is
cross-checked in ngspice: through the force–voltage analogy the cone's mass,
suspension and damping become an inductor, a capacitor and a resistor, the
moving coil a gyrator (two current-controlled voltage sources), all in one
deck compared state by state with the simulation
(lagrangian.compare.compare_with_ngspice).

Run: .venv/bin/python examples/loudspeaker.py [--out loudspeaker.png] [--points 13]
"""

from __future__ import annotations

import argparse
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.compare import compare_with_ngspice
from lagrangian.spice import NgspiceMissingError

RE, LE = 6.0, 0.5e-3  # Ω, H: voice-coil resistance and inductance
BL = 7.0  # T m: force factor
M, K, C = 0.02, 2000.0, 1.5  # kg, N/m, N s/m: moving mass, suspension stiffness and damping
OMEGA = sp.Symbol("omega", positive=True)  # drive frequency, given per simulation


def loudspeaker() -> lg.Model:
    m = lg.Model("loudspeaker")
    m.add("voltage_source", "E", ("n1", "0"), E=sp.sin(OMEGA * lg.t))  # 1 V peak
    m.add("resistor", "Re", ("n1", "n2"), R=RE)
    m.add("inductor", "Le", ("n2", "n3"), L=LE)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=BL)  # current n3 → 0 pushes the cone in +x
    m.add("mass", "m", "cone", m=M)
    m.add("spring", "k", ("ground", "cone"), k=K)
    m.add("damper", "c", ("ground", "cone"), c=C)
    return m


def closed_form(f: np.ndarray) -> np.ndarray:
    """Z(jω) derived by hand: E = (Re + jωLe) I + Bl U, (c + jωm + k/jω) U = Bl I."""
    jw = 2j * np.pi * np.asarray(f, dtype=float)
    return RE + jw * LE + BL**2 / (C + jw * M + K / jw)


def simulated_impedance(model: lg.Model, f: float, coil_charge: str) -> complex:
    """E/I at frequency f from the steady state of a simulation (least-squares fit over the last two periods)."""
    w, period = 2 * np.pi * f, 1 / f
    # the slowest transient decays like exp(−(c + Bl²/Re) t / 2m), i.e. within ~4 ms (rate 250 1/s); run 0.15 s or 6 periods
    cycles = int(np.ceil(max(6 * period, 0.15) / period))
    t_fit = np.linspace((cycles - 2) * period, cycles * period, 400)
    res = model.simulate((0.0, cycles * period), t_eval=t_fit, params={"omega": w}, method="LSODA", rtol=1e-10, atol=1e-13)
    current = res.velocity(coil_charge)
    basis = np.column_stack([np.cos(w * t_fit), np.sin(w * t_fit), np.ones_like(t_fit)])
    (a, b, _), *_ = np.linalg.lstsq(basis, current, rcond=None)
    # phasors X of x(t) = Re(X e^{jωt}): a cos + b sin → a − jb; E = sin(ωt) → −j
    return -1j / (a - 1j * b)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="loudspeaker.png", help="where to write the chart (PNG)")
    parser.add_argument("--points", type=int, default=13, help="number of simulated frequencies (log-spaced, 10 Hz–2 kHz)")
    args = parser.parse_args()

    model = loudspeaker()
    print(model.describe())
    coil_charge = model.coordinate_names[0]  # q_Le: the loop charge through Le and the coil

    fs = np.sqrt(K / M) / (2 * np.pi)
    print(f"\nmechanical resonance f_s = √(k/m)/2π = {fs:.4f} Hz; closed-form peak |Z(f_s)| = Re + Bl²/c = {RE + BL**2 / C:.4f} Ω")
    freqs = np.unique(np.concatenate([np.geomspace(10, 2000, args.points), [fs]]))
    start = time.perf_counter()
    sim = []
    print(f"\n{'f [Hz]':>10} {'|Z| sim [Ω]':>14} {'|Z| closed [Ω]':>15} {'rel. diff':>10} {'∠Z sim [°]':>11} {'∠Z closed [°]':>14}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lg.InitialConditionWarning)  # starts at rest: q = x = 0
        for f in freqs:
            z = simulated_impedance(model, f, coil_charge)
            zc = closed_form(f)
            sim.append(z)
            print(
                f"{f:10.3f} {abs(z):14.6f} {abs(zc):15.6f} {abs(z / zc - 1):10.2e} "
                f"{np.degrees(np.angle(z)):11.4f} {np.degrees(np.angle(zc)):14.4f}"
            )
    sim = np.array(sim)
    worst = np.max(np.abs(sim / closed_form(freqs) - 1))
    peak = int(np.argmax(np.abs(sim)))
    print(f"\nsimulated {len(freqs)} frequencies in {time.perf_counter() - start:.1f} s")
    print(f"max relative difference simulated vs closed-form impedance: {worst:.2e}")
    print(f"impedance peak of the simulated sweep: |Z| = {abs(sim[peak]):.4f} Ω at {freqs[peak]:.4f} Hz (f_s = {fs:.4f} Hz)")

    try:  # the drive at f_s in ngspice
        cmp = compare_with_ngspice(model, 0.1, analogy="force-voltage", params={"omega": 2 * np.pi * fs}, step=1e-4,
                                   max_step=2e-6, method="exact")
    except NgspiceMissingError as exc:
        print(f"\nngspice cross-check skipped: {exc}")
    else:
        print(f"\nngspice cross-check, 0.1 s of the drive at f_s:\n{cmp.table()}")
        print(f"ngspice vs simulation: worst {cmp.worst_rel:.2e} of peak")

    dense = np.geomspace(10, 2000, 600)
    zc = closed_form(dense)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, constrained_layout=True)
    top.semilogx(dense, np.abs(zc), label="closed form Re + jωLe + Bl²/(c + jωm + k/jω)")
    top.semilogx(freqs, np.abs(sim), "o", label="simulated (steady-state E/I)")
    top.axvline(fs, color="k", ls=":", lw=1, label=f"f_s = √(k/m)/2π = {fs:.1f} Hz")
    top.set_ylabel("|Z| [Ω]")
    top.set_title("Loudspeaker input impedance: the mechanical resonance seen from the terminals")
    top.grid(True, which="both", alpha=0.3)
    top.legend(fontsize=8)
    bottom.semilogx(dense, np.degrees(np.angle(zc)))
    bottom.semilogx(freqs, np.degrees(np.angle(sim)), "o")
    bottom.axvline(fs, color="k", ls=":", lw=1)
    bottom.set_ylabel("∠Z [°]")
    bottom.set_xlabel("frequency [Hz]")
    bottom.grid(True, which="both", alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
