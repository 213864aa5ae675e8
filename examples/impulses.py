"""Impulsive motion without integrating anything: Δp = Q̂ with the coordinates held fixed.
=======================================================================================

1. The notes' four-bar linkage (Fig. 2.17): four uniform bars of mass m and
   length 2b pinned in a rhombus, the vertices A and C sliding smoothly on
   the x axis, at rest; an impulse F̂ along x at A.  Generalized impulses in
   the notes' coordinates (x₁: centre of mass, θ: angle of the bars),
   Q̂_x₁ = F̂, Q̂_θ = 2b sin θ F̂, and the acquired velocities
   ẋ₁ = F̂/(4m), θ̇ = 3 sin θ F̂/(8mb) — from a model with six coordinates and
   four loop-closure constraints.
2. The notes' rod (mass m, length 2L) falling flat at speed v onto a knife
   edge at L/2 from its centre, restitution e: ẏ_c = (4e − 3)v/7,
   θ̇ = 6(1 + e)v/(7L), energy lost 2m(1 − e²)v²/7; angular momentum about
   the edge is conserved.  (The notes print ẏ_c = v(4e − v)/7: a typo for
   v(4e − 3)/7, which is what their equations (1)–(4) give.)
3. A free rod (mass m, length ℓ) at rest struck at one end by P̂ across it:
   v_G = P̂/m, ω = 6P̂/(mℓ); the point at 2ℓ/3 from the struck end stays at
   rest (the struck end is the centre of percussion for that point).
4. A double pendulum (bobs m₁, m₂ on massless links l₁, l₂) hanging at rest,
   its lower bob struck horizontally by P̂: θ̇₁ = 0, θ̇₂ = P̂/(m₂l₂) — the
   upper bob does not move.

Writes a chart of the knife-edge velocities against e.

Run: .venv/bin/python examples/impulses.py [--out impulses.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import sympy as sp

import lagrangian as lg
from lagrangian.impulse import Impulse, generalized_impulse, ground, impact, velocity_jump


def rhombus(m, b) -> lg.Model:
    """The notes' four-bar: sliders A and C on the x axis, bars AB, BC (tree from A), CD, DA (tree from C),
    loops closed at C and A."""
    model = lg.Model("rhombus four-bar", dim=2)
    model.add("link", "A", "A")
    model.add("link", "C", "C")
    model.add("prismatic", "sA", ("ground", "A"))
    model.add("prismatic", "sC", ("ground", "C"))
    for bar in ("AB", "BC", "CD", "DA"):
        model.add("rod", bar, bar, m=m, length=2 * b)
    model.add("revolute", "jA", ("A", "AB"), absolute=True)
    model.add("revolute", "jB", ("AB", "BC"), parent_point=(2 * b, 0), absolute=True)
    model.add("revolute", "jC", ("C", "CD"), absolute=True)
    model.add("revolute", "jD", ("CD", "DA"), parent_point=(2 * b, 0), absolute=True)
    model.add("revolute", "closeC", ("BC", "C"), parent_point=(2 * b, 0))
    model.add("revolute", "closeA", ("DA", "A"), parent_point=(2 * b, 0))
    return model


def rhombus_configuration(x1, theta, b) -> dict:
    """The model's six coordinates in terms of the notes' two (x₁, θ)."""
    return {"s_sA": x1 - 2 * b * sp.cos(theta), "s_sC": x1 + 2 * b * sp.cos(theta), "theta_jA": theta,
            "theta_jB": -theta, "theta_jC": theta + sp.pi, "theta_jD": sp.pi - theta}


def four_bar() -> None:
    m, b, F, theta, x1 = sp.symbols("m b F theta x1", positive=True)
    model = rhombus(m, b)
    config = rhombus_configuration(x1, theta, b)
    print(f"1. four-bar: coordinates {model.coordinate_names}, {len(model.eq.constraints)} loop-closure equations")
    Q = generalized_impulse(model, [Impulse("A.origin", (F, 0))], coordinates=config)
    print(f"   generalized impulses (notes' coordinates): Q_x1 = {Q['x1']}, Q_theta = {Q['theta']}")
    print("   closed form:                               Q_x1 = F, Q_theta = 2*b*F*sin(theta)")
    jump = velocity_jump(model, [Impulse("A.origin", (F, 0))], at=config)
    xdot = sp.simplify((jump.after["s_sA"] + jump.after["s_sC"]) / 2)
    thdot = jump.after["theta_jA"]
    print(f"   acquired velocities: x1' = {xdot}, theta' = {thdot}")
    ok = sp.simplify(xdot - F / (4 * m)) == 0 and sp.simplify(thdot - 3 * sp.sin(theta) * F / (8 * m * b)) == 0
    print(f"   closed form:         x1' = F/(4*m), theta' = 3*F*sin(theta)/(8*b*m)   -> symbolic agreement: {ok}")
    values = {"m": 1.0, "b": 0.5}
    numeric = velocity_jump(model, [Impulse("A.origin", (2.0, 0))], at=rhombus_configuration(0.0, np.pi / 3, 0.5),
                            params=values)
    err = max(abs((numeric.after["s_sA"] + numeric.after["s_sC"]) / 2 - 2.0 / 4),
              abs(numeric.after["theta_jA"] - 3 * np.sin(np.pi / 3) * 2.0 / (8 * 0.5)))
    print(f"   numeric (m=1, b=0.5, theta=pi/3, F=2): max |error| = {err:.2e}")


def knife_edge(ax) -> None:
    m, L, v, e = sp.symbols("m L v e", positive=True)
    rod = lg.Model("rod on a knife edge", dim=2)
    rod.add("rod", "rod", "rod", m=m, length=2 * L, points={"P": (3 * L / 2, 0)})
    rod.add("free", "fly", ("ground", "rod"), child_point=(L, 0))
    rod.add("gravity", "g")
    hit = impact(rod, [ground("rod.P", e=e)], at={"theta_fly": 0, "x_fly": 0, "y_fly": 0}, velocity={"y_fly": -v})
    yc, w = hit.after["y_fly"], hit.after["theta_fly"]
    print(f"2. knife edge: y_c' = {yc}, theta' = {w}, impulse = {hit.impulses['ground(rod.P)']}")
    print("   closed form: y_c' = v*(4*e - 3)/7, theta' = 6*v*(e + 1)/(7*L), impulse = 4*m*v*(1 + e)/7")
    lost = sp.factor(hit.energy_lost)
    agree = (sp.simplify(yc - v * (4 * e - 3) / 7) == 0 and sp.simplify(w - 6 * v * (1 + e) / (7 * L)) == 0
             and sp.simplify(lost - 2 * m * (1 - e**2) * v**2 / 7) == 0)
    print(f"   energy lost = {lost}  (closed form 2*m*(1 - e**2)*v**2/7) -> symbolic agreement: {agree}")
    # angular momentum about the edge (the point (L/2, 0)): −m v·(L/2)… before; I ω + m (r_G − r_P) × v_G after
    H = lambda vy, om: m * L**2 / 3 * om + m * (-L / 2) * vy
    print(f"   angular momentum about the edge: before {sp.simplify(H(-v, 0))}, after {sp.simplify(H(yc, w))}")
    es = np.linspace(0, 1, 11)
    num = [impact(rod, [ground("rod.P", e=float(x))], at={"theta_fly": 0.0}, velocity={"y_fly": -1.0},
                  params={"m": 1.0, "L": 1.0}) for x in es]
    err = max(max(abs(j.after["y_fly"] - (4 * x - 3) / 7), abs(j.after["theta_fly"] - 6 * (1 + x) / 7)) for j, x in zip(num, es))
    print(f"   numeric over e = 0, 0.1, ..., 1 (m = L = v = 1): max |error| = {err:.2e}")
    fine = np.linspace(0, 1, 101)
    ax.plot(fine, (4 * fine - 3) / 7, "k-", alpha=0.3, lw=3, label="closed form y_c'/v = (4e − 3)/7")
    ax.plot(fine, 6 * (1 + fine) / 7, "b-", alpha=0.3, lw=3, label="closed form Lθ'/v = 6(1 + e)/7")
    ax.plot(es, [j.after["y_fly"] for j in num], "ko", label="computed y_c'/v")
    ax.plot(es, [j.after["theta_fly"] for j in num], "bs", label="computed Lθ'/v")
    ax.set_xlabel("coefficient of restitution e")
    ax.set_title("rod falling flat on a knife edge at L/2")
    ax.grid(True, alpha=0.3)
    ax.legend()


def struck_rod() -> None:
    m, ell, P = sp.symbols("m ell P", positive=True)
    rod = lg.Model("free rod", dim=2)
    rod.add("rod", "rod", "rod", m=m, length=ell)
    rod.add("free", "fly", ("ground", "rod"), child_point=(ell / 2, 0))
    jump = velocity_jump(rod, [Impulse("rod.end", (0, P))], at={"theta_fly": 0})
    vG, w = jump.after["y_fly"], jump.after["theta_fly"]
    # the point at 2ℓ/3 from the struck end (ℓ/6 from the centre, towards the start): v = v_G − ω ℓ/6
    still = sp.simplify(vG - w * ell / 6)
    print(f"3. free rod struck at its end: v_G = {vG}, omega = {w} (closed form P/m, 6*P/(ell*m)); "
          f"velocity of the point 2*ell/3 from the struck end: {still}")


def double_pendulum() -> None:
    m1, m2, l1, l2, P = sp.symbols("m1 m2 l1 l2 P", positive=True)
    dp = lg.Model("double pendulum", dim=2)
    dp.add("link", "upper", "upper", points={"bob": (l1, 0)})
    dp.add("link", "lower", "lower", points={"bob": (l2, 0)})
    dp.add("revolute", "shoulder", ("ground", "upper"), absolute=True)
    dp.add("revolute", "elbow", ("upper", "lower"), parent_point=(l1, 0), absolute=True)
    dp.add("mass", "m1", "upper.bob", m=m1)
    dp.add("mass", "m2", "lower.bob", m=m2)
    dp.add("gravity", "g")
    down = {"theta_shoulder": -sp.pi / 2, "theta_elbow": -sp.pi / 2}
    jump = velocity_jump(dp, [Impulse("lower.bob", (P, 0))], at=down)
    print(f"4. double pendulum struck at its lower bob: theta1' = {jump.after['theta_shoulder']}, "
          f"theta2' = {jump.after['theta_elbow']} (closed form 0, P/(l2*m2))")
    n = velocity_jump(dp, [Impulse("lower.bob", (1.0, 0.0))], at={"theta_shoulder": -np.pi / 2, "theta_elbow": -np.pi / 2},
                      params={"m1": 1.0, "m2": 2.0, "l1": 1.0, "l2": 0.5})
    print(f"   numeric (m2 = 2, l2 = 0.5, P = 1): theta1' = {n.after['theta_shoulder']:.3e}, theta2' = "
          f"{n.after['theta_elbow']:.12f} (closed form 1.0), kinetic energy acquired {-n.energy_lost:.12f} (P²/(2 m2) = 0.25)")


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="impulses.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    four_bar()
    knife_edge(ax)
    struck_rod()
    double_pendulum()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
