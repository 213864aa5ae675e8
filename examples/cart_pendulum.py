"""A pendulum hanging from a cart: on a free cart, and on a cart moved at constant speed.
======================================================================================

The pendulum is a point mass m on a massless link of length L pinned to the
cart (absolute angle θ from the x axis: hanging is θ = −π/2); the cart slides
along x on a prismatic joint.

1. Free cart of mass M, no friction, no force along x: the horizontal
   momentum p = (M + m) ẋ − m L sin θ θ̇ is conserved (x is ignorable), and the
   small oscillations have ω² = g (M + m) / (M L) (by hand: the centre of mass
   stays put, so the bob swings about it on a shortened arm L M / (M + m)).
   The script prints the simulated and the closed-form frequency and the
   momentum drift.
2. Cart driven at constant speed v (a driven prismatic joint, no
   coordinate): Galilean invariance — the pendulum swings exactly as on a
   fixed pivot, θ̈ = −(g/L) cos θ.  The script prints the largest difference
   from that equation integrated by SciPy, and the Jacobi integral
   h = Σ q̇ ∂L/∂q̇ − L: conserved (L has no explicit t), while the total
   energy T + V is not (h − (T + V) = m v L sin θ θ̇ − (M + m) v²).

Run: .venv/bin/python examples/cart_pendulum.py [--t-end 20] [--out cart_pendulum.png]
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
from scipy.integrate import solve_ivp

import lagrangian as lg
from lagrangian import routh

G, L, M_CART, M_BOB, V_CART = 9.81, 0.7, 2.0, 0.5, 1.5
TIGHT = {"rtol": 1e-12, "atol": 1e-14}


def cart_pendulum(speed: float | None = None) -> lg.Model:
    """The free cart (speed None), or a cart driven at the given constant speed."""
    model = lg.Model("cart and pendulum" if speed is None else "cart at constant speed", dim=2)
    model.add("body", "cart", "cart", m=M_CART, inertia=0.1)
    model.add("link", "arm", "arm", points={"bob": (L, 0)})
    motion = {} if speed is None else {"displacement": speed * lg.t}
    model.add("prismatic", "rail", ("ground", "cart"), **motion)
    model.add("revolute", "pivot", ("cart", "arm"), absolute=True)
    model.add("mass", "bob", "arm.bob", m=M_BOB)
    model.add("gravity", "g", g=G)
    return model


def upward_crossings(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    return t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--t-end", type=float, default=20.0, help="simulated time span [s]")
    parser.add_argument("--out", default="cart_pendulum.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)

    # 1. free cart: small-oscillation frequency and momentum
    model = cart_pendulum()
    print(f"free cart: coordinates {model.coordinate_names}")
    res = model.simulate(args.t_end, initial={"s_rail": 0.0, "theta_pivot": -math.pi / 2 + 1e-3},
                         velocity={"s_rail": 0.0, "theta_pivot": 0.0}, points=int(400 * args.t_end) + 1, **TIGHT)
    crossings = upward_crossings(res.t, res["theta_pivot"] + math.pi / 2 - float(np.mean(res["theta_pivot"] + math.pi / 2)))
    exact = math.sqrt(G * (M_CART + M_BOB) / (M_CART * L))
    if len(crossings) >= 2:
        print(f"  small oscillations: ω simulated {2 * math.pi / np.mean(np.diff(crossings)):.8f} rad/s, "
              f"closed form √(g (M + m) / (M L)) = {exact:.8f} rad/s (fixed pivot: √(g/L) = {math.sqrt(G / L):.4f})")
    x, th = (sp.Function(n, real=True)(lg.t) for n in model.coordinate_names)
    momentum = (M_CART + M_BOB) * x.diff(lg.t) - M_BOB * L * sp.sin(th) * th.diff(lg.t)
    big = model.simulate(args.t_end, initial={"s_rail": 0.0, "theta_pivot": 0.0},
                         velocity={"s_rail": 0.4, "theta_pivot": 0.0}, points=int(100 * args.t_end) + 1, **TIGHT)
    p = big.quantity(momentum)
    print(f"  released horizontal: momentum p = {p[0]:.6f}, relative drift {np.max(np.abs(p - p[0])) / abs(p[0]):.2e}; "
          f"relative energy drift {big.energy_drift():.2e}")
    left.plot(big.t, big["s_rail"], label="cart position s")
    left.plot(big.t, big["theta_pivot"], label="pendulum angle θ")
    left.set_title("free cart, pendulum released horizontal")
    left.set_xlabel("t [s]")
    left.legend()

    # 2. cart driven at constant speed: the fixed-pivot pendulum equation
    model = cart_pendulum(V_CART)
    print(f"cart at constant speed {V_CART} m/s: coordinates {model.coordinate_names}")
    res = model.simulate(args.t_end, initial={"theta_pivot": -math.pi / 2 + 1.2}, velocity={"theta_pivot": 0.0},
                         points=int(50 * args.t_end) + 1, rtol=1e-11, atol=1e-13)
    ref = solve_ivp(lambda _, y: [y[1], -G / L * math.cos(y[0])], (0, args.t_end), [-math.pi / 2 + 1.2, 0.0],
                    t_eval=res.t, rtol=1e-12, atol=1e-13, method="DOP853")
    gap = float(np.max(np.abs(res["theta_pivot"] - ref.y[0])))
    print(f"  max |θ − fixed-pivot pendulum θ̈ = −(g/L) cos θ| = {gap:.2e} rad")
    jacobi = routh.jacobi_integral(model)
    print(f"  Jacobi integral h = {jacobi.expr}: {'conserved' if jacobi.conserved else 'not conserved'}; "
          f"h − (T + V) = {jacobi.difference}")
    print(f"  along the run: relative drift of h {jacobi.drift(res):.2e}, of the total energy T + V {res.energy_drift():.2e} "
          f"(work is done to keep the cart's speed)")
    right.plot(res.t, res["theta_pivot"], lw=2.5, label="on the moving cart")
    right.plot(res.t, ref.y[0], "k--", lw=1, label="fixed pivot (SciPy)")
    right.set_title(f"cart at {V_CART} m/s: the same swing as on a fixed pivot")
    right.set_xlabel("t [s]")
    right.legend()
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
