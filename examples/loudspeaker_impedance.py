"""A loudspeaker's input impedance, three ways, on one chart.
==========================================================

1. From its coupled Lagrangian (voice-coil circuit, moving coil L ∋ Bl·x·q̇,
   cone on its suspension): ``lagrangian.frequency.impedance`` of the
   source, exact in the Laplace domain.
2. From its mechanical view: the cone alone, driven by a force, has the
   mechanical impedance Z_m = F/v = c + jωm + k/jω; seen through the coil it
   adds the motional impedance (Bl)²/Z_m to the coil's Re + jωLe.
3. From its equivalent circuit: the force–voltage analogue (the cone's mass,
   suspension and damping an inductor, a capacitor and a resistor; the coil
   a gyrator) run through ngspice's AC analysis.

All three are compared with the closed form
Z(jω) = Re + jωLe + (Bl)²/(c + jωm + k/jω), whose peak Re + (Bl)²/c sits at
the mechanical resonance f_s = √(k/m)/2π.

Run: .venv/bin/python examples/loudspeaker_impedance.py [--out loudspeaker_impedance.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import lagrangian as lg
from lagrangian import frequency
from lagrangian.ac import compare_ac_with_ngspice
from lagrangian.analogy import map_model
from lagrangian.spice import NgspiceMissingError

RE, LE = 6.0, 0.5e-3  # Ω, H: voice-coil resistance and inductance
BL = 7.0  # T m: force factor
M, K, C = 0.02, 2000.0, 1.5  # kg, N/m, N s/m: moving mass, suspension stiffness and damping


def loudspeaker() -> lg.Model:
    m = lg.Model("loudspeaker")
    m.add("voltage_source", "E", ("n1", "0"), E=0)
    m.add("resistor", "Re", ("n1", "n2"), R=RE)
    m.add("inductor", "Le", ("n2", "n3"), L=LE)
    m.add("moving_coil", "coil", ("n3", "0", "cone"), Bl=BL)
    m.add("mass", "m", "cone", m=M)
    m.add("spring", "k", ("ground", "cone"), k=K)
    m.add("damper", "c", ("ground", "cone"), c=C)
    return m


def cone() -> lg.Model:
    m = lg.Model("cone")
    m.add("mass", "m", "cone", m=M)
    m.add("spring", "k", ("ground", "cone"), k=K)
    m.add("damper", "c", ("ground", "cone"), c=C)
    m.add("force", "F", "cone", F=0)
    return m


def closed_form(f: np.ndarray) -> np.ndarray:
    jw = 2j * np.pi * np.asarray(f, dtype=float)
    return RE + jw * LE + BL**2 / (C + jw * M + K / jw)


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="loudspeaker_impedance.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    fs = np.sqrt(K / M) / (2 * np.pi)
    model = loudspeaker()
    Z = frequency.impedance(model, "E")
    print(f"Z(s) from the coupled Lagrangian: {Z.expr}")
    print(f"poles {np.round(Z.poles(), 4)} rad/s, zeros {np.round(Z.zeros(), 4)} rad/s, DC {Z.dc_gain:.6g} Ω")

    f = frequency.decades(10, 2000, 200)
    jw = 2j * np.pi * f
    closed = closed_form(f)
    lagrangian_z = Z(jw)
    Zm = frequency.impedance(cone(), "F")
    mechanical_z = RE + jw * LE + BL**2 / Zm(jw)
    print(f"mechanical impedance of the cone: Z_m(s) = {Zm.expr}")
    rows = [("coupled Lagrangian", lagrangian_z), ("mechanical view", mechanical_z)]
    spice_f = spice_z = None
    try:
        analogue = map_model(model, "force-voltage").model
        cmp = compare_ac_with_ngspice(analogue, input="E", outputs=["i(E)"], start=10, stop=2000, points=200)
        spice_f, spice_z = cmp.frequencies, -1 / cmp.spice["i(E)"]  # ngspice's i(E) flows into the + terminal
        print(f"\n{cmp.table()}")
    except NgspiceMissingError as exc:
        print(f"\nngspice skipped: {exc}")
    print(f"\nmechanical resonance f_s = √(k/m)/2π = {fs:.4f} Hz; closed-form peak Re + Bl²/c = {RE + BL**2 / C:.6f} Ω")
    for name, z in rows:
        print(f"{name:20s} max |Z/Z_closed − 1| = {np.max(np.abs(z / closed - 1)):.2e}")
    if spice_z is not None:
        print(f"{'equivalent circuit':20s} max |Z/Z_closed − 1| = {np.max(np.abs(spice_z / closed_form(spice_f) - 1)):.2e}")
    peak = np.abs(Z(2j * np.pi * fs))
    print(f"|Z(f_s)| from the Lagrangian = {peak:.6f} Ω")

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True, constrained_layout=True)
    top.semilogx(f, np.abs(closed), color="0.6", lw=5, alpha=0.5, label="closed form")
    top.semilogx(f, np.abs(lagrangian_z), lw=1.6, label="coupled Lagrangian")
    top.semilogx(f, np.abs(mechanical_z), "--", lw=1.2, label="Re + jωLe + Bl²/Z_m (mechanical view)")
    bottom.semilogx(f, np.degrees(np.angle(closed)), color="0.6", lw=5, alpha=0.5)
    bottom.semilogx(f, np.degrees(np.angle(lagrangian_z)), lw=1.6)
    bottom.semilogx(f, np.degrees(np.angle(mechanical_z)), "--", lw=1.2)
    if spice_z is not None:
        top.semilogx(spice_f[::8], np.abs(spice_z[::8]), "o", ms=4, label="equivalent circuit (ngspice .ac)")
        bottom.semilogx(spice_f[::8], np.degrees(np.angle(spice_z[::8])), "o", ms=4)
    for ax in (top, bottom):
        ax.axvline(fs, color="k", ls=":", lw=1)
        ax.grid(True, which="both", alpha=0.3)
    top.set_ylabel("|Z| (Ω)")
    bottom.set_ylabel("∠Z (°)")
    bottom.set_xlabel("frequency (Hz)")
    top.set_title(f"Loudspeaker input impedance: resonance at f_s = {fs:.1f} Hz")
    top.legend(fontsize=8)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
