"""A torque-free rigid body: conserved energy and angular momentum, and the intermediate-axis flip.
================================================================================================

A body with principal moments I = (3, 2, 1) along its x, y, z axes turns
freely about its centre of mass (a spherical joint there, no gravity).  It is
spun at Ω about each principal axis in turn, with a small wobble (ε ≪ Ω about
the other two).  Euler's equations say spin about the largest or the smallest
moment is stable, while spin about the intermediate one is not: the wobble
grows like e^{λt}, λ = Ω √((I₁ − I₂)(I₂ − I₃) / (I₁ I₃)), and the body
flips over and back again and again (the Dzhanibekov effect).

For each run the script prints the relative drift of the kinetic energy and
of the angular momentum L = R I ω_body (R the body's rotation, from its pose),
and how far the spin axis strays from L: cos(axis, L) stays near 1 for the
major and minor axes, and swings to −1 and back for the intermediate one.

The spherical joint uses body-fixed x-y-z Euler angles, singular when the
body z axis points along the fixed x axis; each run is oriented so that L
keeps well away from that (``|β|`` is printed).

Run: .venv/bin/python examples/spinning_body.py [--t-end 20] [--out spinning_body.png]
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
from scipy.spatial.transform import Rotation
from scipy.special import ellipk

import lagrangian as lg

I = (3.0, 2.0, 1.0)
OMEGA, EPS = 2.0, 0.01
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def free_body() -> lg.Model:
    m = lg.Model("torque-free body", dim=3)
    m.add("body", "b", "b", m=1.0, inertia=I)
    m.add("spherical", "ball", ("ground", "b"))
    return m


#: axis index, initial Euler angles, initial Euler rates (ω in the fixed frame; at α = β = 0 the rates are its
#: components): major axis x and minor axis z from the identity; the intermediate axis y turned onto the fixed x
#: axis by γ = −π/2 (ω_fixed = Rz(−π/2) ω_body = (ω_y, −ω_x, ω_z)).
RUNS = {
    "major": (0, (0.0, 0.0, 0.0), (OMEGA, EPS, EPS)),
    "intermediate": (1, (0.0, 0.0, -math.pi / 2), (OMEGA, -EPS, EPS)),
    "minor": (2, (0.0, 0.0, 0.0), (EPS, EPS, OMEGA)),
}


def flip_interval(rates, angles) -> float:
    """Time between sign changes of ω₂ (the intermediate component) from the closed-form solution of Euler's
    equations (Landau & Lifshitz, Mechanics §37): with I₁ < I₂ < I₃ and L² > 2 E I₂, ω₂ ∝ sn(p t, k), p² =
    (I₃ − I₂)(L² − 2 E I₁)/(I₁ I₂ I₃), k² = (I₂ − I₁)(2 E I₃ − L²)/((I₃ − I₂)(L² − 2 E I₁)); sn changes sign every
    2K(k)/p.  (For L² < 2 E I₂ the roles of I₁ and I₃ swap.)"""
    R = Rotation.from_euler("XYZ", angles).as_matrix()  # intrinsic x-y-z: R = Rx Ry Rz
    w = R.T @ np.asarray(rates)  # at α = β = 0 the Euler rates are ω in the fixed frame
    i1, i2, i3 = sorted(I)
    order = [I.index(v) for v in (i1, i2, i3)]
    w1, w2, w3 = (w[j] for j in order)
    E2 = i1 * w1**2 + i2 * w2**2 + i3 * w3**2
    L2 = (i1 * w1) ** 2 + (i2 * w2) ** 2 + (i3 * w3) ** 2
    if L2 < E2 * i2:
        i1, i3 = i3, i1
    p = math.sqrt((i3 - i2) * (L2 - E2 * i1) / (i1 * i2 * i3))
    k2 = (i2 - i1) * (E2 * i3 - L2) / ((i3 - i2) * (L2 - E2 * i1))
    return 2 * ellipk(k2) / p


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--t-end", type=float, default=20.0, help="simulated time span [s]")
    parser.add_argument("--out", default="spinning_body.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    model = free_body()
    names = model.coordinate_names
    pose = model.assembly.views["mechanical"].pose("b")
    L_expr = pose.R * sp.diag(*I) * pose.R.T * pose.omega
    lam = OMEGA * math.sqrt((I[0] - I[1]) * (I[1] - I[2]) / (I[0] * I[2]))
    print(f"principal moments {I}; spin Ω = {OMEGA} rad/s, wobble ε = {EPS} rad/s")
    print(f"intermediate axis: linear growth rate λ = Ω √((I₁ − I₂)(I₂ − I₃)/(I₁ I₃)) = {lam:.4f} 1/s")
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True, constrained_layout=True)
    for label, (axis, angles, rates) in RUNS.items():
        res = model.simulate(args.t_end, initial=dict(zip(names, angles)), velocity=dict(zip(names, rates)),
                             points=int(100 * args.t_end) + 1, **TIGHT)
        L = np.array([res.quantity(c) for c in L_expr])
        L0 = L[:, 0]
        drift_L = float(np.max(np.linalg.norm(L - L0[:, None], axis=0)) / np.linalg.norm(L0))
        spin_axis = np.array([res.quantity(pose.R[i, axis]) for i in range(3)])
        cosine = L0 @ spin_axis / np.linalg.norm(L0)
        flips = int(np.sum(np.diff(np.sign(cosine)) != 0))
        print(f"spin about the {label} axis (I = {I[axis]:g}):")
        print(f"  relative drift: energy {res.energy_drift():.2e}, angular momentum {drift_L:.2e}")
        print(f"  cos(spin axis, L) ranges over [{cosine.min():.6f}, {cosine.max():.6f}]; sign changes: {flips}; "
              f"max |β| = {np.max(np.abs(res['beta_ball'])):.3f} rad")
        if flips:
            i = np.flatnonzero(np.diff(np.sign(cosine)) != 0)
            crossings = res.t[i] - cosine[i] * (res.t[i + 1] - res.t[i]) / (cosine[i + 1] - cosine[i])
            print(f"  the spin axis is square to L at t = {', '.join(f'{c:.4f}' for c in crossings)} s")
            if len(crossings) >= 2:
                print(f"  time between flips: simulated {np.mean(np.diff(crossings)):.6f} s, closed form 2K(k)/p = "
                      f"{flip_interval(rates, angles):.6f} s")
        top.plot(res.t, cosine, label=f"{label} axis (I = {I[axis]:g})")
        bottom.semilogy(res.t, np.maximum(np.linalg.norm(L - L0[:, None], axis=0) / np.linalg.norm(L0), 1e-18), label=label)
    top.set_ylabel("cos(spin axis, L)")
    top.set_title("torque-free body: spin about the intermediate axis flips")
    top.legend(loc="lower left")
    bottom.set_ylabel("|L(t) − L(0)| / |L(0)|")
    bottom.set_xlabel("t [s]")
    bottom.legend()
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
