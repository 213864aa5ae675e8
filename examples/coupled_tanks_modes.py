"""The normal modes of two inductively coupled LC tanks.
=====================================================

Two identical tanks (L, C) whose inductors are coupled by k share two
modes: in phase, at ω² = 1/((1 + k) L C), and in antiphase, at
ω² = 1/((1 − k) L C).  ``lagrangian.frequency.modes`` finds them from the
Lagrangian (the coupling is the mutual co-energy k√(L₁L₂)·i₁i₂), in both
circuit formulations, with their shapes; the frequency response of the
second tank's voltage to a current injected in the first peaks at both,
and a small resistance across each tank gives the modes their damping.
Writes a chart of the response and the mode shapes.

Run: .venv/bin/python examples/coupled_tanks_modes.py [--out coupled_tanks.png]
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

L, C, K = 7e-3, 2.2e-6, 0.3  # H, F, coupling coefficient


def tanks(formulation: str, R: float | None = None) -> lg.Model:
    m = lg.Model("coupled tanks", formulation=formulation)
    m.add("current_source", "I1", ("0", "n1"), I=0)
    for i in (1, 2):
        m.add("inductor", f"L{i}", (f"n{i}", "0"), L=L)
        m.add("capacitor", f"C{i}", (f"n{i}", "0"), C=C)
        if R is not None:
            m.add("resistor", f"R{i}", (f"n{i}", "0"), R=R)
    m.add("coupling", "K1", inductor1="L1", inductor2="L2", k=K)
    return m


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="coupled_tanks.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    closed = np.sort(1 / np.sqrt(np.array([1 + K, 1 - K]) * L * C)) / (2 * np.pi)
    print(f"closed form: f = 1/(2π √((1 ± k) L C)) = {closed[0]:.6f} Hz, {closed[1]:.6f} Hz")
    for formulation in ("charge", "flux"):
        found = frequency.modes(tanks(formulation))
        shapes = ", ".join(f"({s[0]:+.3f}, {s[1]:+.3f})" for s in found.shapes.T)
        print(f"{formulation:6s} formulation: {found.frequencies[0]:.6f} Hz, {found.frequencies[1]:.6f} Hz "
              f"(max rel. difference {np.max(np.abs(found.frequencies / closed - 1)):.1e}); shapes {shapes}")
    damped = tanks("flux", R=2e3)
    found = frequency.modes(damped)
    print(f"with 2 kΩ across each tank: {found}")
    f = frequency.decades(500, 5000, 400)
    resp = frequency.frequency_response(damped, f, inputs=["I1"], outputs=["v(n1)", "v(n2)"])
    peaks = [f[i] for i in range(1, len(f) - 1) if abs(resp["v(n2)"][i]) > max(abs(resp["v(n2)"][i - 1]), abs(resp["v(n2)"][i + 1]))]
    print(f"peaks of |v(n2)/I1|: {', '.join(f'{p:.1f} Hz' for p in peaks)}")

    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), constrained_layout=True)
    for label in resp.outputs:
        left.semilogx(f, 20 * np.log10(np.abs(resp[label])), label=f"{label} / I1")
    for fc in closed:
        left.axvline(fc, color="k", ls=":", lw=1)
    left.set_xlabel("frequency (Hz)")
    left.set_ylabel("|Z| (dB Ω)")
    left.set_title("response to a current into tank 1 (dotted: closed-form modes)")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=8)
    undamped = frequency.modes(tanks("flux"))
    for j in range(2):
        right.plot([1, 2], undamped.shapes[:, j], "o-", label=f"{undamped.frequencies[j]:.1f} Hz")
    right.set_xticks([1, 2], ["tank 1", "tank 2"])
    right.axhline(0, color="k", lw=0.5)
    right.set_ylabel("mode shape (node flux linkage)")
    right.set_title("in phase (slow) and in antiphase (fast)")
    right.legend(fontsize=8)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
