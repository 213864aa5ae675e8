"""The spherical pendulum in the notes' angles: Routhian, steady motion, its stability, and the pole.
==================================================================================================

A bob of mass m on a massless arm of length l hangs from two revolute
joints: ``turn`` about the vertical (φ) and ``tilt`` about the turning
horizontal axis (θ, from the downward vertical), so that
L = ½ m l² (φ̇² sin² θ + θ̇²) + m g l cos θ exactly as in the notes.

The script prints:

1. the Routhian, equation (2.94), the effective potential (2.95), the
   steady-motion condition (2.96) and the perturbation equation
   s̈ + (g/l)(3 cos θ₀ + sec θ₀) s = 0, all derived symbolically;
2. a simulation of the full model started near a steady motion at
   θ₀ = 0.7 rad: the oscillation frequency of θ against the linear
   prediction;
3. the edges: a start at the pole with C ≠ 0 is refused (infinite
   barrier), the motion with small C turns back at the barrier, and with
   C = 0 the reduced model swings straight through the pole.

Run: .venv/bin/python examples/spherical_steady.py [--out spherical_steady.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian import routh

G, L_ARM, M_BOB = 9.81, 1.0, 1.0
TIGHT = {"rtol": 1e-12, "atol": 1e-13}


def spherical(m=M_BOB, l=L_ARM, g=G) -> lg.Model:
    model = lg.Model("spherical pendulum", dim=3)
    model.add("link", "yoke", "yoke")
    model.add("revolute", "turn", ("ground", "yoke"), axis=(0, 0, 1))
    model.add("link", "arm", "arm", points={"bob": (0, 0, -l)})
    model.add("revolute", "tilt", ("yoke", "arm"), axis=(1, 0, 0))
    model.add("mass", "bob", "arm.bob", m=m)
    model.add("gravity", "g", g=g)
    return model


def upward(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="spherical_steady.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    # 1. the notes, symbolically
    m, l, g = sp.symbols("m l g", positive=True)
    sym = routh.reduce(spherical(m, l, g))
    print(f"R     = {sym.routhian}")
    (eq,) = sym.equations
    print(f"(2.94) {eq.lhs} = {eq.rhs}")
    print(f"(2.95) V_eff = {sym.effective_potential}")
    print(f"singular where {', '.join(map(str, sym.singularities))} = 0")
    sm = sym.steady_motions(solve_for=["C_theta_turn"])[1]
    th0 = sp.Symbol("theta_tilt_0", real=True)
    print(f"steady motion: C = {sm.momenta['theta_turn']}, so l φ̇₀² = {sp.simplify(l * sm.rates['theta_turn'] ** 2)}  (2.96)")
    (pert,) = sm.perturbation().equations
    w2 = sm.perturbation().frequency_squared
    print(f"perturbation: {pert.lhs} = 0, ω² = {w2}")
    print(f"  equals (g/l)(3 cos θ₀ + sec θ₀): {sp.simplify(w2 - g / l * (3 * sp.cos(th0) + 1 / sp.cos(th0))) == 0}")

    # 2. near a steady motion, numerically
    model = spherical()
    red = routh.reduce(model)
    theta0 = 0.7
    rate = math.sqrt(G / (L_ARM * math.cos(theta0)))
    C = M_BOB * L_ARM**2 * math.sin(theta0) ** 2 * rate
    (steady,) = [s for s in red.steady_motions(momenta={"theta_turn": C}) if float(s.coordinates["theta_tilt"]) > 0]
    st = steady.stability()
    predicted = math.sqrt(G / L_ARM * (3 * math.cos(theta0) + 1 / math.cos(theta0)))
    res = model.simulate(20, initial={"theta_tilt": theta0 + 1e-4, "theta_turn": 0}, velocity={"theta_turn": rate, "theta_tilt": 0},
                         points=20001, **TIGHT)
    s = res["theta_tilt"] - np.mean(res["theta_tilt"])
    simulated = 2 * math.pi / float(np.mean(np.diff(upward(res.t, s))))
    print(f"steady motion at θ₀ = {float(steady.coordinates['theta_tilt']):.12f} for C = {C:.6f}: {st}")
    print(f"  perturbation frequency: linear {st.frequencies[0]:.8f}, closed form {predicted:.8f}, "
          f"full-model simulation {simulated:.8f} rad/s (relative {abs(simulated - predicted) / predicted:.1e})")

    # 3. the pole
    try:
        red.simulate(1, initial={"theta_tilt": 0.0}, velocity={"theta_tilt": 1.0}, momenta={"theta_turn": 0.05})
    except lg.ReductionError as exc:
        print(f"start at the pole with C = 0.05: ReductionError: {exc}")
    barrier = red.simulate(1.5, initial={"theta_tilt": 0.5}, velocity={"theta_tilt": -3.0}, momenta={"theta_turn": 0.05},
                           points=3001, **TIGHT)
    through = red.simulate(1.5, initial={"theta_tilt": 0.5, "theta_turn": 0.0}, velocity={"theta_tilt": -3.0},
                           momenta={"theta_turn": 0.0}, reconstruct=True, points=3001, **TIGHT)
    print(f"C = 0.05: θ turns back at {np.min(barrier['theta_tilt']):.5f} rad (the barrier); "
          f"C = 0: θ reaches {np.min(through['theta_tilt']):.5f} rad through the pole, φ stays {through['theta_turn'][-1]:.1f}")

    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)
    left.plot(res.t, res["theta_tilt"], label="θ (full model)")
    left.axhline(theta0, color="k", lw=0.6, label="θ₀")
    left.set_xlim(0, 5)
    left.set_xlabel("t [s]")
    left.set_title(f"near steady motion: ω = {simulated:.5f} (linear {predicted:.5f})")
    left.legend()
    right.plot(barrier.t, barrier["theta_tilt"], label="C = 0.05: barrier")
    right.plot(through.t, through["theta_tilt"], label="C = 0: through the pole")
    right.axhline(0, color="k", lw=0.6)
    right.set_xlabel("t [s]")
    right.set_ylabel("θ [rad]")
    right.set_title("the pole sin θ = 0")
    right.legend()
    fig.savefig(args.out, dpi=120)
    print(f"chart: {args.out}")


if __name__ == "__main__":
    main()
