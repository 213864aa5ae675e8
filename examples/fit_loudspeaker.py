"""Thiele–Small parameters of a loudspeaker, fitted to its measured impedance.
===========================================================================

A driver's six parameters (Re, Le, Bl, the moving mass Mms, the suspension's stiffness k = 1/Cms and its
damping Rms) are what one measures it for.  Its electrical impedance
Z(jω) = Re + jωLe + Bl²/(Rms + jωMms + k/jω) is what a meter reads.  Here the "measurements" are that closed
form with 0.5 % complex noise: a free-air curve, and a second one with 10 g added to the cone.

``lagrangian.fit`` adjusts the model's parameters with the exact Jacobian of its linearization.  The free-air
curve alone cannot separate Bl from Mms, Cms and Rms: scaling Bl by λ and the other three by λ² (λ⁻² for Cms)
leaves Z unchanged, and the fit says so.  The added-mass curve resolves it, and every true value then lies in
its 3σ interval.

Run: .venv/bin/python examples/fit_loudspeaker.py [--out fit_loudspeaker.png]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import lagrangian as lg
from lagrangian import models

TRUTH = {"R_Re": 6.0, "L_Le": 0.5e-3, "Bl_coil": 7.0, "m_m": 0.02, "k_k": 2000.0, "c_c": 1.5}
ADDED = 0.010  # kg on the cone for the second curve
F = np.geomspace(5, 5000, 200)  # Hz


def impedance(f: np.ndarray, added: float = 0.0) -> np.ndarray:
    """The closed form, the true values."""
    p, w = TRUTH, 2 * np.pi * f
    return p["R_Re"] + 1j * w * p["L_Le"] + p["Bl_coil"] ** 2 / (p["c_c"] + 1j * w * (p["m_m"] + added) + p["k_k"] / (1j * w))


def speaker(added: float = 0.0) -> lg.Model:
    """The model at a first guess, some 30 % off; with ``added`` kg on the cone."""
    model = models.loudspeaker(Re=5.0, Le=0.8e-3, Bl=5.0, m=0.03, k=1500.0, c=1.0)
    if added:
        model.add("mass", "added", "cone", m=added)
    return model


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="fit_loudspeaker.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    rng = np.random.default_rng(2)

    def measured(z):
        return z * (1 + 0.005 * (rng.normal(size=z.size) + 1j * rng.normal(size=z.size)) / np.sqrt(2))

    free = lg.FrequencyData(F, measured(impedance(F)), input="E", output="i(Le)", impedance=True, name="free air")
    loaded = lg.FrequencyData(F, measured(impedance(F, ADDED)), input="E", output="i(Le)", impedance=True,
                              model=speaker(ADDED), name="+10 g")

    alone = lg.fit(speaker(), free, list(TRUTH))
    print("free air alone:")
    print(alone)
    both = lg.fit(speaker(), [free, loaded], list(TRUTH))
    print("free air and +10 g:")
    print(both)
    bounds = both.interval(3.0)
    for name, true in TRUTH.items():
        low, high = bounds[name]
        print(f"{name:>8}: true {true:.6g}, fitted {both.values[name]:.6g} "
              f"({abs(both.values[name] / true - 1):.1e} off), in its 3σ interval: {low <= true <= high}")

    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    both.plot(ax)
    ax.set_ylabel("|Z| (Ω)")
    ax.set_title("loudspeaker impedance: measured (dots) and fitted (lines)")
    fig.savefig(args.out, dpi=120)
    print(f"chart written to {args.out}")
