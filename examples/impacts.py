"""Hybrid simulation with impacts: a bouncing ball coming to rest, a pendulum hitting a wall.
==========================================================================================

1. A ball dropped from height h onto the ground, restitution e < 1.  Impact
   k comes at t_k = t₁ + 2v₁(e + … + e^{k−1})/g (t₁ = √(2h/g), v₁ = √(2gh)),
   infinitely many of them before t_∞ = t₁ + 2v₁e/(g(1 − e)) (Zeno).  The
   simulation switches to resting contact near t_∞ and stays on the ground;
   the script prints the impact times against the sequence, the Zeno point,
   the energy lost at each impact against (1 − e²)·½mv², and the final state.
2. A pendulum (bob on a massless link of length ℓ) released at angle α from
   the vertical against a wall through its pivot: each impact reverses the
   angular velocity scaled by e, so the amplitude satisfies
   sin(α_{j}/2) = e^j sin(α/2), and impact j comes at
   t_j = √(ℓ/g)·[K(k₀²) + 2 Σ_{i<j} K(k_i²)] (K the complete elliptic integral,
   k_i = sin(α_i/2)).  Printed against the simulation.

Writes a chart of both motions.

Run: .venv/bin/python examples/impacts.py [--out impacts.png]
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.special import ellipk

import lagrangian as lg
from lagrangian.impulse import ground, simulate_with_impacts, wall

G = 9.81


def bouncing_ball(ax, h=1.0, e=0.6, mass=0.5) -> None:
    ball = lg.Model("bouncing ball")
    ball.add("mass", "m", "ball", m=mass)
    ball.add("gravity", "g", g=G)
    v1, t1 = math.sqrt(2 * G * h), math.sqrt(2 * h / G)
    t_inf = t1 + 2 * v1 * e / (G * (1 - e))
    res = simulate_with_impacts(ball, 2 * t_inf, [ground("ball", e=e)], initial={"x_ball": h}, velocity={"x_ball": 0.0},
                                points=2001)
    exact = t1 + np.array([2 * v1 * sum(e**i for i in range(1, k + 1)) / G for k in range(len(res.impacts))])
    times = res.impact_times
    print(f"1. bouncing ball (h = {h}, e = {e}): {len(res.impacts)} impacts simulated before resting contact")
    for k in range(4):
        print(f"   impact {k + 1}: t = {times[k]:.12f}, closed form {exact[k]:.12f}")
    print(f"   max |t_k − closed form| over all impacts = {np.max(np.abs(times - exact)):.2e} s")
    lost = np.array([r.energy_lost for r in res.impacts[:-1]])  # the last one is the plastic switch to rest
    speeds = v1 * e ** np.arange(len(lost))
    print(f"   max |energy lost − (1 − e²)·½ m v_k²| = {np.max(np.abs(lost - (1 - e**2) * mass * speeds**2 / 2)):.2e} J")
    rest_t = res.resting[0][0]
    print(f"   Zeno point t_inf = {t_inf:.9f} s; resting contact from t = {rest_t:.9f} s (|difference| {abs(t_inf - rest_t):.1e} s)")
    print(f"   at t = {res.t[-1]:.3f} s: height {res['x_ball'][-1]:.2e} m, velocity {res.velocity('x_ball')[-1]:.2e} m/s; "
          f"total energy lost {res.energy_lost:.9f} J (m g h = {mass * G * h:.9f} J)")
    ax.plot(res.t, res["x_ball"], "b-", lw=1)
    ax.plot(times, np.zeros_like(times), "r|", ms=10, label="impacts")
    ax.axvline(t_inf, color="k", ls=":", label="Zeno point t∞")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("height [m]")
    ax.set_title(f"bouncing ball, e = {e}: resting contact after t∞")
    ax.legend()


def pendulum_wall(ax, ell=1.0, alpha=1.2, e=0.8, impacts=5) -> None:
    pend = lg.Model("pendulum against a wall", dim=2)
    pend.add("link", "arm", "arm", points={"bob": (ell, 0)})
    pend.add("revolute", "pin", ("ground", "arm"), absolute=True)
    pend.add("mass", "m", "arm.bob", m=1.0)
    pend.add("gravity", "g", g=G)
    k = [math.sin(alpha / 2) * e**j for j in range(impacts)]
    tau = math.sqrt(ell / G)
    exact = tau * (ellipk(k[0] ** 2) + 2 * np.concatenate([[0], np.cumsum([ellipk(x**2) for x in k[1:]])]))
    res = simulate_with_impacts(pend, exact[-1] + 0.5 * tau, [wall("arm.bob", 0.0, side=+1, e=e)],
                                initial={"theta_pin": -math.pi / 2 + alpha}, velocity={"theta_pin": 0.0},
                                rtol=1e-12, atol=1e-14, points=2001)
    times = res.impact_times[:impacts]
    print(f"2. pendulum against a wall (alpha = {alpha}, e = {e}): {len(res.impacts)} impacts")
    for j in range(impacts):
        r = res.impacts[j]
        print(f"   impact {j + 1}: t = {times[j]:.12f}, closed form {exact[j]:.12f}; "
              f"omega after/before = {r.after['theta_pin'] / r.before['theta_pin']:+.12f}")
    print(f"   max |t_j − closed form| = {np.max(np.abs(times - exact)):.2e} s")
    ax.plot(res.t, res["theta_pin"] + math.pi / 2, "g-", lw=1)
    ax.plot(times, np.zeros_like(times), "r|", ms=10, label="impacts on the wall")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("angle from the vertical [rad]")
    ax.set_title(f"pendulum hitting a wall, e = {e}")
    ax.legend()


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").partition("\n")[0])
    parser.add_argument("--out", default="impacts.png", help="where to write the chart (PNG)")
    args = parser.parse_args()
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 4.5), constrained_layout=True)
    bouncing_ball(left)
    pendulum_wall(right)
    for ax in (left, right):
        ax.grid(True, alpha=0.3)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    print(f"chart written to {out}")


if __name__ == "__main__":
    main()
