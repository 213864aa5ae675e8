"""Transmissibility of a base-excited mass–spring–damper (a vibration isolator).
=============================================================================

A mass m sits on a spring k and a damper c whose other end is a base moved
by a prescribed motion y(t).  The transfer function from the base's motion
to the mass's is H(s) = (c s + k)/(m s² + c s + k); its magnitude on the
imaginary axis is the transmissibility

    ``|T(r)|`` = √(1 + (2ζr)²) / √((1 − r²)² + (2ζr)²),   r = ω/ωn,

which every curve crosses at r = √2: above it the isolator isolates, and
more damping isolates less.  The base enters through the damper's velocity,
so H has the zero −k/c: the Laplace form takes s·y exactly.

Run: .venv/bin/python examples/isolator_transmissibility.py [--out transmissibility.png]
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

MASS, STIFFNESS = 12.0, 4.7e4  # kg, N/m: ωn = 62.6 rad/s, fn = 9.96 Hz


def isolator(c: float) -> lg.Model:
    m = lg.Model("isolator")
    m.add("prescribed_motion", "base", "b", position=0)
    m.add("mass", "m", "p", m=MASS)
    m.add("spring", "k", ("b", "p"), k=STIFFNESS)
    m.add("damper", "c", ("b", "p"), c=c)
    return m


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="transmissibility.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    wn = np.sqrt(STIFFNESS / MASS)
    f = frequency.decades(wn / (2 * np.pi) / 20, wn / (2 * np.pi) * 20, 100)
    r = 2 * np.pi * f / wn
    fig, ax = plt.subplots(figsize=(7.5, 5), constrained_layout=True)
    worst = 0.0
    for zeta in (0.02, 0.1, 0.3, 0.7):
        c = 2 * zeta * np.sqrt(STIFFNESS * MASS)
        model = isolator(c)
        H = frequency.transfer_function(model, "base", "x_p")
        T = np.abs(H(2j * np.pi * f))
        closed = np.sqrt(1 + (2 * zeta * r) ** 2) / np.sqrt((1 - r**2) ** 2 + (2 * zeta * r) ** 2)
        worst = max(worst, float(np.max(np.abs(T / closed - 1))))
        at_root2 = abs(H(1j * np.sqrt(2) * wn))
        print(f"ζ = {zeta:4.2f}: H(s) = {H.expr}; zero {H.zeros()[0].real:.2f} rad/s; |T| at r = √2: {at_root2:.12f}; "
              f"peak {T.max():.4f}")
        ax.loglog(r, T, label=f"ζ = {zeta}")
    print(f"max relative difference from the closed form: {worst:.2e}")
    ax.axvline(np.sqrt(2), color="k", ls=":", lw=1)
    ax.axhline(1, color="k", lw=0.5)
    ax.set_xlabel("frequency ratio r = ω/ωn")
    ax.set_ylabel("transmissibility |x/y|")
    ax.set_title("Base-excited mass–spring–damper: isolation above r = √2")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
