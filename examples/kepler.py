"""The central-force (Kepler) problem reduced to one degree of freedom through the Routhian.
=========================================================================================

A planet of mass m rides a bead on a massless arm turning about the sun
(revolute ``orbit``: θ; prismatic ``radius``: r) and is attracted by
``central_force`` k/r².  θ is ignorable, p_θ = m r² θ̇ = C (the angular
momentum), and the Routhian R = −½ m ṙ² + C²/(2 m r²) − k/r leaves the
radial equation (2.89) of the notes.

The script prints:

1. the Routhian, the effective potential and the reduced equation;
2. the circular orbit r₀ = C²/(m k) and its radial frequency ω_r² = k/(m r₀³)
   (equal to the orbital rate: the perturbed orbit closes), with the
   stability verdict, against a simulation started just off the circle;
3. an eccentric orbit: the radial period against Kepler's third law
   2π √(m a³/k) (a = −k/(2E)), and θ(t) reconstructed by quadrature against
   the full two-coordinate model;
4. the bifurcation: with a force k/rⁿ circular orbits are stable for n < 3,
   marginal at n = 3 (a zero eigenvalue), unstable beyond.

Run: .venv/bin/python examples/kepler.py [--out kepler.png]
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

M, K = 1.0, 1.0
TIGHT = {"rtol": 1e-12, "atol": 1e-13}


def central(m=M, k=K, n=2) -> lg.Model:
    model = lg.Model("kepler", dim=2)
    model.add("link", "arm", "arm")
    model.add("revolute", "orbit", ("ground", "arm"), absolute=True)
    model.add("link", "bead", "bead")
    model.add("prismatic", "radius", ("arm", "bead"))
    model.add("mass", "planet", "bead", m=m)
    model.add("central_force", "sun", ("ground", "bead"), k=k, n=n)
    return model


def upward(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="kepler.png", help="where to write the chart (PNG)")
    args = parser.parse_args()

    m, k = sp.symbols("m k", positive=True)
    symbolic = routh.reduce(central(m, k))
    print(f"ignorable: {routh.ignorable(symbolic.full)}")
    print(f"R     = {symbolic.routhian}")
    print(f"V_eff = {symbolic.effective_potential}")
    (eq,) = symbolic.equations
    print(f"reduced equation: {eq.lhs} = {eq.rhs}")
    for sm in symbolic.steady_motions():
        print(f"  circular orbit: r0 = {sm.coordinates['s_radius']}, radial ω² = {sm.perturbation().frequency_squared}, "
              f"θ̇ = {sm.rates['theta_orbit']}")

    model = central()
    red = routh.reduce(model)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 5), constrained_layout=True)

    # 2. circular orbit and its radial oscillation
    C = 1.2
    (sm,) = [s for s in red.steady_motions(momenta={"theta_orbit": C}) if float(s.coordinates["s_radius"]) > 0]
    r0 = float(sm.coordinates["s_radius"])
    st = sm.stability()
    omega = math.sqrt(K / (M * r0**3))
    res = red.simulate(40, initial={"s_radius": r0 * (1 + 1e-4)}, velocity={"s_radius": 0}, momenta={"theta_orbit": C},
                       points=40001, **TIGHT)
    simulated = 2 * math.pi / float(np.mean(np.diff(upward(res.t, res["s_radius"] - r0))))
    print(f"circular orbit for C = {C}: r0 = {r0:.12f} (C²/(m k) = {C**2 / (M * K):.12f}); {st}")
    print(f"  radial frequency: linear {st.frequencies[0]:.10f}, closed form √(k/(m r0³)) = {omega:.10f}, "
          f"simulated {simulated:.10f} rad/s")

    # 3. an eccentric orbit: period and reconstruction
    initial, velocity = {"s_radius": 1.0, "theta_orbit": 0.0}, {"s_radius": 0.3, "theta_orbit": 0.75}
    E = 0.5 * M * (0.3**2 + 0.75**2) - K / 1.0  # at r = 1
    a = -K / (2 * E)
    period = 2 * math.pi * math.sqrt(M * a**3 / K)
    span = 3 * period
    reduced = red.simulate(span, initial=initial, velocity=velocity, reconstruct=True, points=30001, **TIGHT)
    full = model.simulate(span, initial=initial, velocity=velocity, points=30001, **TIGHT)
    radial = float(np.mean(np.diff(upward(reduced.t, -reduced.v["s_radius"]))))
    gap = max(float(np.max(np.abs(reduced[n] - full[n]))) for n in full.names)
    print(f"eccentric orbit: radial period {radial:.10f} s, Kepler 2π√(m a³/k) = {period:.10f} s "
          f"(relative difference {abs(radial - period) / period:.1e})")
    print(f"  reduced + reconstructed θ vs full model: max difference {gap:.1e}")
    r, th = reduced["s_radius"], reduced["theta_orbit"]
    left.plot(r * np.cos(th), r * np.sin(th), label="reduced + reconstructed")
    left.plot(full["s_radius"][::50] * np.cos(full["theta_orbit"][::50]), full["s_radius"][::50] * np.sin(full["theta_orbit"][::50]),
              ".", ms=3, label="full model")
    left.plot([0], [0], "*", color="orange", ms=12, label="sun")
    left.set_aspect("equal")
    left.set_title("Kepler orbit")
    left.legend()

    # 4. bifurcation at n = 3
    rr = np.linspace(0.4, 3, 400)
    for n in (2.5, 3.0, 3.5):
        red_n = routh.reduce(central(n=n))
        if n == 3.0:
            family = red_n.steady_motions(solve_for=["C_theta_orbit"])
            st = family[0].stability({"s_radius_0": 1.0})
            print(f"force k/r^{n}: circular orbits only for C = {sorted(float(f.momenta['theta_orbit']) for f in family)}, "
                  f"at any radius: {st}")
            Cn = 1.0
        else:
            Cn = 1.0
            (sm,) = red_n.steady_motions(momenta={"theta_orbit": Cn}, search={"s_radius": (0.1, 10)})
            st = sm.stability()
            print(f"force k/r^{n}: circular orbit r0 = {float(sm.coordinates['s_radius']):.6f}: {st.verdict} "
                  f"(V_eff'' = {st.curvature[0]:.4g})")
        veff = sp.lambdify(sp.Symbol("r"), red_n.effective_potential.subs({
            sp.Symbol("C_theta_orbit", real=True): Cn}).replace(sp.Abs, lambda x: x).subs(
            sp.Function("s_radius", real=True)(lg.t), sp.Symbol("r")), "numpy")
        right.plot(rr, veff(rr) * np.ones_like(rr), label=f"n = {n}")
    right.set_ylim(-0.6, 0.6)
    right.set_xlabel("r")
    right.set_ylabel("V_eff (C = 1)")
    right.set_title("effective potential: stable, marginal, unstable")
    right.legend()
    fig.savefig(args.out, dpi=120)
    print(f"chart: {args.out}")


if __name__ == "__main__":
    main()
